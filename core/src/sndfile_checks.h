// Opening audio files with libsndfile, shared by read_audio and AudioFileReader.
#pragma once

#include <sndfile.h>

#include <cstddef>
#include <filesystem>

namespace avsi {

// Opens `path` for reading and fills `info`: a file with a valid rate and
// channel count, at least one frame, and the whole data chunk its header
// declares (require_whole_data_chunk); float reads of it scaled as PCM to
// [-1, 1) and float files as they are. Throws InputError naming the file
// otherwise. The caller closes the handle.
SNDFILE* open_audio_file(const std::filesystem::path& path, SF_INFO& info);

// Throws InputError when `file`'s header declares more audio data than the
// file holds (a copy cut short: libsndfile then reads what is there and
// says so only in its log, as `data : <declared bytes> (should be <bytes
// present>)`). `present_frames` at `rate_hz` is what it found. The
// placeholder sizes of writers that could not go back to fill them in (0
// and 0xFFFFFFFF) pass.
void require_whole_data_chunk(const std::filesystem::path& path, SNDFILE* file, std::size_t present_frames,
                              int rate_hz);

}  // namespace avsi
