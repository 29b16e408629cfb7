// Edinburgh Speech Tools (EST) track files, the format MOCHA-TIMIT and mngu0
// ship their EMA data in (.ema): a text header
//
//     EST_File Track
//     DataType binary            (or ascii)
//     ByteOrder 10               (10 = big-endian, 01 = little-endian; binary only)
//     NumFrames 2
//     NumChannels 4
//     NumAuxChannels 0
//     EqualSpace 1
//     BreaksPresent true
//     CommentChar ;
//     Channel_0 ui_x             (channel_N or Channel_N: the channel's name)
//     …
//     EST_Header_End
//
// followed by the frames: per frame the time in seconds, the break flag when
// BreaksPresent (0 = no value at this frame, nonzero = a value), then the
// channel values — whitespace-separated text lines for ascii, float32 for
// binary. Also reads sensor CSV (`time_s,<channel>…`) into the same struct.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace avsi::learn {

struct EstTrack {
    std::vector<std::string> channels;        // channel names in file order
    std::vector<double> times_s;              // per frame
    std::vector<bool> present;                // per frame; false where the break flag is 0
    std::vector<std::vector<float>> values;   // frames × channels
    bool equal_space = true;

    std::size_t frame_count() const { return times_s.size(); }
    // Index of a channel by name, or npos.
    std::size_t channel(const std::string& name) const;
    static constexpr std::size_t npos = static_cast<std::size_t>(-1);
};

enum class EstDataType { Ascii, Binary };
enum class EstByteOrder { BigEndian, LittleEndian };

// Reads an EST track file (ascii or binary, either byte order). Malformed
// headers or truncated data throw InputError naming the file, line and field.
EstTrack read_est_track(const std::filesystem::path& path);

// Writes an EST track file with BreaksPresent true.
void write_est_track(const std::filesystem::path& path, const EstTrack& track, EstDataType type,
                     EstByteOrder order = EstByteOrder::LittleEndian);

// Reads sensor coordinates from CSV: a `time_s` (or `time`) column and one
// column per channel; empty or "nan" cells mark a frame without data.
EstTrack read_sensor_csv(const std::filesystem::path& path);

// Reads a sensor file chosen by extension: .csv → CSV, .mat → Haskins
// (haskins_mat.h), anything else → EST.
EstTrack read_sensor_file(const std::filesystem::path& path);

}  // namespace avsi::learn
