// A protocol and corpus of any size for the experiment tests: conditions,
// lists, warm-up and practice sentences as a test asks for them.
#pragma once

#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "avsi/core/files.h"

namespace avsi::test {

struct GeneratedStudy {
    int conditions = 6;
    int per_list = 3;
    int warmup = 2;
    int practice = 2;
    std::string counterbalance = "latin-square";
    bool list_column = true;
    int seed = 11;
    int extra_sentences = 0;  // unassigned sentences (no list column only)
};

// Writes protocol.toml and corpus.csv into `dir`; returns the protocol path.
inline std::filesystem::path write_study(const std::filesystem::path& dir, const GeneratedStudy& g) {
    std::string corpus = g.list_column ? "id,text,keywords,list\n" : "id,text,keywords\n";
    int n = 0;
    auto add = [&](const std::string& list) {
        ++n;
        corpus += fmt::format("s{:03},The word{} is here.,word{}", n, n, n);
        if (g.list_column) corpus += "," + list;
        corpus += "\n";
    };
    for (int i = 0; i < g.warmup; ++i) add("warmup");
    for (int i = 0; i < g.practice; ++i) add("practice");
    for (int l = 1; l <= g.conditions; ++l)
        for (int i = 0; i < g.per_list; ++i) add(std::to_string(l));
    for (int i = 0; i < g.extra_sentences; ++i) add("");
    write_text_file(dir / "corpus.csv", corpus);
    std::string protocol = fmt::format("[experiment]\nname = \"generated\"\nseed = {}\n\n[corpus]\nsentences = \"corpus.csv\"\n\n",
                                       g.seed);
    for (int c = 0; c < g.conditions; ++c) protocol += fmt::format("[[condition]]\nname = \"c{}\"\n\n", c + 1);
    protocol += fmt::format(
        "[design]\nlists = {}\nsentences_per_list = {}\nwarmup = {}\npractice = {}\ncounterbalance = \"{}\"\n\n"
        "[session]\nfullscreen = false\nfixation_ms = 100\nresponse_delay_ms = 50\n",
        g.conditions, g.per_list, g.warmup, g.practice, g.counterbalance);
    write_text_file(dir / "protocol.toml", protocol);
    return dir / "protocol.toml";
}

}  // namespace avsi::test
