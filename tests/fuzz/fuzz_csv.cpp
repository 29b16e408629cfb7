// libFuzzer harness: the CSV parser (quoted fields across lines, BOM, comments).
#include "avsi/core/csv.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        (void)avsi::parse_csv(text, "in.csv");
        avsi::CsvOptions tsv;
        tsv.delimiter = '\t';
        (void)avsi::parse_csv(text, "in.tsv", tsv);
    });
}
