// The synthetic reference speaker closes its lips for every bilabial and
// brings the lower lip to the upper incisors for every labiodental, measured
// on the built-in head (issue 17: the data-driven models can only close
// what their training data closes).
#include <unistd.h>

#include <gtest/gtest.h>

#include <filesystem>

#include "avsi/learn/articulatory_corpus.h"
#include "avsi/learn/reference_speaker.h"
#include "avsi/stimuli/articulation.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::learn;

TEST(ReferenceSpeaker, ClosesEveryBilabialAndReachesEveryLabiodentalOnTheBuiltInHead) {
    const fs::path dir = fs::temp_directory_path() / (std::to_string(::getpid()) + "_avsi_refcorpus_articulation");
    fs::remove_all(dir);
    ReferenceSpeakerSettings s;
    s.max_utterances = 60;
    write_reference_corpus(dir, s);
    const ArticulatoryCorpus corpus = load_articulatory_corpus(dir);
    const stimuli::Head head = stimuli::load_default_head();
    const stimuli::ArticulationMeter meter(head);
    std::size_t bilabials = 0, labiodentals = 0;
    std::string problems;
    for (const auto& e : corpus.entries) {
        const CorpusUtterance u = load_corpus_utterance(corpus, e);
        synth::Trajectory t;
        t.fps = u.track.fps;
        t.frames = u.track.frames;
        const auto summary = synth::check_articulation(u.phones, t.fps, meter.measure(t));
        bilabials += summary.bilabials;
        labiodentals += summary.labiodentals;
        for (const auto& p : summary.problems()) problems += e.id + ": " + p + "\n";
    }
    EXPECT_GT(bilabials, 100u);
    EXPECT_GT(labiodentals, 40u);
    EXPECT_TRUE(problems.empty()) << problems;
    fs::remove_all(dir);
}
