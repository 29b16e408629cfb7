// The running-speech sentences of the articulation and animation-layer tests
// (tests/data/articulation/sentences.txt) and their phones as espeak-ng
// (en-us) times them.
#pragma once

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"

namespace avsi::test {

// The sentences, one a line ('#' comments and blank lines skipped).
inline std::vector<std::string> test_sentences() {
    std::vector<std::string> out;
    std::ifstream in(std::filesystem::path(AVSI_TEST_DATA_DIR) / "articulation" / "sentences.txt");
    for (std::string line; std::getline(in, line);)
        if (!trim(line).empty() && line[0] != '#') out.push_back(trim(line));
    return out;
}

struct Utterance {
    std::string text;
    PhoneSequence phones;
};

// The sentences timed by espeak-ng (en-us), synthesised once per process.
inline const std::vector<Utterance>& utterances() {
    static const std::vector<Utterance> u = [] {
        std::vector<Utterance> out;
        for (const auto& s : test_sentences()) out.push_back({s, synthesize_speech(s).phones});
        return out;
    }();
    return u;
}

}  // namespace avsi::test
