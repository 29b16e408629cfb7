// libFuzzer harness: the optical marker readers (C3D; Qualisys TSV and Motive
// CSV when the input looks like text of theirs).
#include "avsi/learn/markers.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view text) {
        const char* name = text.starts_with("Format Version") ? "in.csv"
                           : text.starts_with("NO_OF") || text.starts_with("MARKER") ? "in.tsv"
                                                                                      : "in.c3d";
        (void)avsi::learn::read_marker_file(avsi::fuzz::input_file(name, text));
    });
}
