// The cochlear-implant simulation options of the vocoder (ci_simulation.h),
// declared once for every command that vocodes (`avsi vocode`,
// `avsi calibrate`): pulse carriers' rate, width and phase, current spread,
// synthesis filter order, insertion-depth shift and n-of-m selection.
// Header-only, for commands whose helper links avsi_vocoder.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "avsi/vocoder/vocoder.h"
#include "one_of.h"

namespace avsi::cli {

// The options given as names, parsed by apply_ci_options.
struct CiOptionNames {
    std::string pulse_phase = "interleaved";
    std::string current_spread = "none";
};

// Adds the options to `sub`, writing into `v` and `names`.
inline void add_ci_options(CLI::App& sub, vocoder::VocoderSettings& v, CiOptionNames& names) {
    using vocoder::CurrentSpread;
    using vocoder::PulsePhase;
    sub.add_option("--pulse-rate", v.pulse_rate_hz, "Pulses per second in each band (pulse-train, poisson carriers)")
        ->capture_default_str();
    sub.add_option("--pulse-width-us", v.pulse_width_us, "Width of each rectangular pulse (µs)")->capture_default_str();
    sub.add_option("--pulse-phase", names.pulse_phase,
                   "Pulse-train phases: interleaved (band b at b/bands of a period, as CIs stimulate) or simultaneous")
        ->capture_default_str()
        ->check(one_of({to_string(PulsePhase::Interleaved), to_string(PulsePhase::Simultaneous)}));
    sub.add_option("--current-spread", names.current_spread,
                   "Current spread: none, db-per-octave or db-per-mm (each envelope also drives the other carrier "
                   "bands, decaying by --spread-slope-db)")
        ->capture_default_str()
        ->check(one_of({to_string(CurrentSpread::None), to_string(CurrentSpread::DbPerOctave),
                        to_string(CurrentSpread::DbPerMm)}));
    sub.add_option("--spread-slope-db", v.spread_slope_db, "Decay of the current spread (dB per octave or per mm)")
        ->capture_default_str();
    sub.add_option("--synthesis-order", v.synthesis_filter_order,
                   "Butterworth prototype order of the carrier band filters (0: the analysis order)")
        ->capture_default_str();
    sub.add_option("--insertion-shift-mm", v.insertion_shift_mm,
                   "Carrier bands this many mm basal of the analysis bands (Greenwood; negative: apical)")
        ->capture_default_str();
    sub.add_option("--n-of-m", v.n_of_m, "Keep the n bands of largest energy in each frame (0: all)")
        ->capture_default_str();
    sub.add_option("--selection-rate", v.selection_frame_rate_hz, "Frames per second of the n-of-m selection")
        ->capture_default_str();
}

// The named options into `v`.
inline void apply_ci_options(const CiOptionNames& names, vocoder::VocoderSettings& v) {
    v.pulse_phase = vocoder::parse_pulse_phase(names.pulse_phase, "--pulse-phase");
    v.current_spread = vocoder::parse_current_spread(names.current_spread, "--current-spread");
}

}  // namespace avsi::cli
