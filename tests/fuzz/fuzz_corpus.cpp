// libFuzzer harness: the articulatory corpus manifest (load_articulatory_corpus)
// beside the EMA support files of the malformed corpus (utt.est, utt.tsv,
// long.tsv), then every utterance it lists loaded (sensors → parameters).
#include "avsi/learn/articulatory_corpus.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const auto path = avsi::fuzz::input_file("corpus.json", text);
        static const bool copied = [&] {
            const auto support = std::filesystem::path(AVSI_TEST_DATA_DIR) / "malformed" / "_support" / "sensors";
            for (const char* f : {"utt.est", "utt.tsv", "long.tsv"})
                std::filesystem::copy_file(support / f, path.parent_path() / f, std::filesystem::copy_options::overwrite_existing);
            return true;
        }();
        (void)copied;
        const auto corpus = avsi::learn::load_articulatory_corpus(path);
        for (const auto& entry : corpus.entries) (void)avsi::learn::load_corpus_utterance(corpus, entry);
    });
}
