// The names the vocoder's options take (`avsi vocode`, `mix`, `stoi`,
// `calibrate`), spelled by the vocoder library's to_string, for one_of
// (one_of.h). Header-only, for commands whose helper links avsi_vocoder.
#pragma once

#include <string>
#include <vector>

#include "avsi/vocoder/channels.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::cli {

// --spacing: greenwood, log, linear (explicit edges come with --edges-hz).
inline std::vector<std::string> band_spacing_names() {
    using vocoder::BandSpacing;
    return {to_string(BandSpacing::Greenwood), to_string(BandSpacing::Log), to_string(BandSpacing::Linear)};
}

// --envelope: rectify, full-wave, hilbert.
inline std::vector<std::string> envelope_method_names() {
    using vocoder::EnvelopeMethod;
    return {to_string(EnvelopeMethod::HalfWaveRectify), to_string(EnvelopeMethod::FullWaveRectify),
            to_string(EnvelopeMethod::Hilbert)};
}

// --carrier: noise, sine, low-noise, pulse-train, poisson (pshc is named so
// that the vocoder's validation says why it is refused).
inline std::vector<std::string> carrier_type_names() {
    using vocoder::CarrierType;
    return {to_string(CarrierType::Noise),      to_string(CarrierType::Sine),
            to_string(CarrierType::LowNoise),   to_string(CarrierType::PulseTrain),
            to_string(CarrierType::PoissonPulses), to_string(CarrierType::Pshc)};
}

// --snr-reference: whole, active.
inline std::vector<std::string> snr_reference_names() {
    using vocoder::SnrReference;
    return {to_string(SnrReference::WholeSignal), to_string(SnrReference::ActiveFrames)};
}

// --channels: mono, keep (vocoder::parse_channel_mode).
inline std::vector<std::string> channel_mode_names() { return {"mono", "keep"}; }

}  // namespace avsi::cli
