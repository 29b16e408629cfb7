// Checks of files libsndfile opened, shared by read_audio and AudioFileReader.
#pragma once

#include <sndfile.h>

#include <cstddef>
#include <filesystem>

namespace avsi {

// Throws InputError when `file`'s header declares more audio data than the
// file holds (a copy cut short: libsndfile then reads what is there and
// says so only in its log, as `data : <declared bytes> (should be <bytes
// present>)`). `present_frames` at `rate_hz` is what it found. The
// placeholder sizes of writers that could not go back to fill them in (0
// and 0xFFFFFFFF) pass.
void require_whole_data_chunk(const std::filesystem::path& path, SNDFILE* file, std::size_t present_frames,
                              int rate_hz);

}  // namespace avsi
