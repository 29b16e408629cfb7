// A small protocol for the animation-layer tests (stimuli's layers test and
// the experiment's player test): two conditions of the rule model on the
// stimuli build corpus, "plain" and "expressive", the second followed by the
// [condition.layers] table the test gives.
#pragma once

#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "avsi/core/files.h"

namespace avsi::test {

// Writes the protocol named `experiment` to `path` with `layers` (TOML
// lines, e.g. "[condition.layers]\ngaze = true\n", or "") after the
// "expressive" condition.
inline void write_layers_protocol(const std::filesystem::path& path, const std::string& experiment,
                                  const std::string& layers) {
    const std::filesystem::path rule = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "rule.json";
    write_text_file(path, fmt::format(R"([experiment]
name = "{}"
seed = 3
[corpus]
sentences = "{}"
[[condition]]
name = "plain"
model = "{}"
[[condition]]
name = "expressive"
model = "{}"
{}
[design]
lists = 2
sentences_per_list = 1
warmup = 0
practice = 0
)",
                                      experiment,
                                      (std::filesystem::path(AVSI_TEST_DATA_DIR) / "stimuli" / "build" / "corpus.csv").string(),
                                      rule.string(), rule.string(), layers));
}

}  // namespace avsi::test
