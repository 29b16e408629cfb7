// Opening audio files with libsndfile, shared by read_audio and AudioFileReader.
#pragma once

#include <sndfile.h>

#include <filesystem>

namespace avsi {

// Opens `path` for reading and fills `info`: a file with a valid rate and
// channel count, at least one frame, and the whole data chunk its header
// declares (a WAV cut short is refused, naming both lengths); float reads
// of it scaled as PCM to [-1, 1) and float files as they are. Throws
// InputError naming the file otherwise. The caller closes the handle.
SNDFILE* open_audio_file(const std::filesystem::path& path, SF_INFO& info);

// Whether `info` is of a float or double file (whose samples may be NaN or
// infinite, unlike PCM's).
inline bool has_float_samples(const SF_INFO& info) {
    const int encoding = info.format & SF_FORMAT_SUBMASK;
    return encoding == SF_FORMAT_FLOAT || encoding == SF_FORMAT_DOUBLE;
}

}  // namespace avsi
