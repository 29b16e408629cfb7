// Writes the marker-fit benchmark's input (bench/bench_marker_fit.sh): a
// synthetic C3D recording of the built-in head's 35 markers (its own rig
// driven by known tracks, with noise, head motion, a lab transform and 3 %
// dropouts: tests/learn/synthetic_markers.h), its phone labels (TSV, one
// 0.2 s segment after another) and the recording list.
//
//   marker_fit_data OUT_DIR [FRAMES]      (default 36000: 10 minutes at 60 fps)
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <fmt/format.h>

#include "avsi/stimuli/head.h"
#include "avsi/stimuli/marker_layout.h"
#include "c3d_test_writer.h"
#include "synthetic_markers.h"

int main(int argc, char** argv) {
    if (argc < 2) {
        std::cerr << "usage: marker_fit_data OUT_DIR [FRAMES]\n";
        return 2;
    }
    const std::filesystem::path out = argv[1];
    std::filesystem::create_directories(out);
    avsi::test::SyntheticMarkerSpec spec;
    spec.frames = argc > 2 ? std::strtoul(argv[2], nullptr, 10) : 36000;
    const auto head = avsi::stimuli::load_default_head();
    const auto model = avsi::stimuli::load_marker_model(head, avsi::stimuli::default_marker_layout());
    std::vector<avsi::synth::Frame> truth;
    const auto rec = avsi::test::synthetic_recording(model, spec, truth);
    avsi::test::C3dWriteSpec c3d;
    c3d.floats = true;
    c3d.labels = rec.labels;
    c3d.frames = rec.frames;
    c3d.xyz = rec.xyz;
    avsi::test::write_c3d_file(out / "take.c3d", c3d);
    std::ofstream labels(out / "take.tsv");
    labels << "start_s\tend_s\tphone\n";
    const char* phones[] = {"sil", "AA1", "M", "IY1", "P", "UW1", "F", "S"};
    const double duration = double(spec.frames) / spec.rate_hz;
    for (int i = 0; 0.2 * i < duration; ++i)
        labels << fmt::format("{:.3f}\t{:.3f}\t{}\n", 0.2 * i, std::min(duration, 0.2 * (i + 1)), phones[i % 8]);
    std::ofstream(out / "recordings.csv") << "id,markers,labels\ntake,take.c3d,take.tsv\n";
    std::cout << fmt::format("wrote {} frames of {} markers to {}\n", rec.frames, rec.marker_count(), out.string());
    return 0;
}
