// Degrading speech files for a study: optional masking noise (before or
// after vocoding), the vocoder, and the same over every WAV of a folder in
// parallel on all cores, with progress through avsi::Progress.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/vocoder/channels.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::vocoder {

enum class NoiseKind { None, SpeechShaped, File };
enum class NoiseStage { BeforeVocoding, AfterVocoding };

struct NoiseSettings {
    NoiseKind kind = NoiseKind::None;
    std::filesystem::path file;                   // NoiseKind::File
    std::vector<std::filesystem::path> ltas_from; // SpeechShaped: WAVs or folders; empty: the inputs themselves
    NoiseStage stage = NoiseStage::BeforeVocoding;
    MixSettings mix;                              // SNR, reference, seed
};

struct ProcessSettings {
    bool vocode = true;
    VocoderSettings vocoder;
    NoiseSettings noise;
    ChannelMode channels = ChannelMode::Mono;  // a multi-channel input: mixed down (default) or kept (channels.h)
};

// What happened to one file.
struct FileReport {
    std::filesystem::path input, output;
    double duration_s = 0.0;
    double vocoder_limit_gain_db = 0.0;  // < 0 when the vocoder output was scaled down
    double mix_limit_gain_db = 0.0;      // < 0 when the mixture was scaled down
    ChannelSelection selection = {};     // n-of-m: the bands kept per frame
};

// Every *.wav (case-insensitive) directly in `folder`, sorted by name.
// Throws InputError when the folder does not exist or holds none.
std::vector<std::filesystem::path> list_wav_files(const std::filesystem::path& folder);

// The long-term spectrum of WAV files and folders of them.
LongTermSpectrum long_term_spectrum_of(const std::vector<std::filesystem::path>& files_or_folders);

// Noise (if any) and vocoding (if on) of one signal, mixed down to mono first
// unless settings.channels keeps the channels (the note names `source`).
// `ltas` is required for speech-shaped noise; `noise_samples` for a noise
// file (at the audio rate); `noise_seed` seeds the speech-shaped noise and
// the excerpt choice.
Audio process_audio(const Audio& input, const ProcessSettings& settings, const LongTermSpectrum* ltas,
                    const std::vector<double>* noise_samples, std::uint64_t noise_seed, FileReport* report = nullptr,
                    const std::string& source = "audio");

// Reads `input`, processes it, writes `output` (16-bit WAV). The noise seed
// is derived from the seed and the file name, as in process_folder.
FileReport process_file(const std::filesystem::path& input, const std::filesystem::path& output,
                        const ProcessSettings& settings);

// Processes every WAV in `input_folder` into `output_folder` (same names)
// on `threads` threads (0: all cores). Speech-shaped noise uses one LTAS for
// the whole folder and a per-file seed derived from the seed and the file
// name. Problems with single files are collected and thrown together.
std::vector<FileReport> process_folder(const std::filesystem::path& input_folder,
                                       const std::filesystem::path& output_folder, const ProcessSettings& settings,
                                       unsigned threads = 0);

// A report of the noise settings for a methods section (empty when none).
std::string describe(const NoiseSettings& noise);

}  // namespace avsi::vocoder
