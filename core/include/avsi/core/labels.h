// Time-aligned label files: Praat TextGrid (long and short text formats,
// UTF-8 and UTF-16), HTK .lab (100 ns units) and TSV (start end label, in
// seconds), and their conversion to phone sequences in the project phone set.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/phones.h"

namespace avsi {

struct Interval {
    double start_s = 0.0;
    double end_s = 0.0;
    std::string text;
    int line = 0;  // source line of the label (0 if not read from a file); not compared

    bool operator==(const Interval& other) const {
        return start_s == other.start_s && end_s == other.end_s && text == other.text;
    }
};

struct Tier {
    std::string name;
    bool is_interval = true;     // point tiers ("TextTier") keep start_s == end_s
    double start_s = 0.0;
    double end_s = 0.0;
    std::vector<Interval> items;
    bool operator==(const Tier&) const = default;
};

struct TextGrid {
    double start_s = 0.0;
    double end_s = 0.0;
    std::vector<Tier> tiers;
    bool operator==(const TextGrid&) const = default;

    // The tier of that name; throws InputError (naming `path` and the tiers
    // present) if there is none.
    const Tier& tier(const std::string& name, const std::string& path = {}) const;
};

// Reads a TextGrid in the long ("ooTextFile" with item [1]: …) or short text
// format, UTF-8 (with or without BOM) or UTF-16 (LE/BE with BOM). Malformed
// files throw InputError with file:line.
TextGrid read_textgrid(const std::filesystem::path& path);
// Writes the long text format in UTF-8.
void write_textgrid(const std::filesystem::path& path, const TextGrid& grid);

// HTK label file: "start end label [score]" per line, times in 100 ns units.
std::vector<Interval> read_htk_lab(const std::filesystem::path& path);
// TSV: "start_s end_s label" per line (tab or space separated; an optional
// header line "start_s end_s phone" is skipped).
std::vector<Interval> read_label_tsv(const std::filesystem::path& path);

// Phones from label intervals: symbols are read as project ARPAbet labels
// first, then as MFA IPA; empty labels, "sp", "sil", "<eps>" become `sil`.
// Gaps between intervals are filled with `sil`. Unknown symbols throw
// InputError naming the file and line/interval.
PhoneSequence phones_from_intervals(const std::vector<Interval>& intervals,
                                    const std::string& source_path);

struct LabelReadOptions {
    std::string tier = "phones";  // TextGrid tier holding phones
};
// Reads phones from a .TextGrid, .lab or .tsv file, chosen by extension.
PhoneSequence read_phones(const std::filesystem::path& path, const LabelReadOptions& options = {});

// Writes phones as TSV ("start_s\tend_s\tphone" with a header line).
void write_phones_tsv(const std::filesystem::path& path, const PhoneSequence& phones);
// Writes phones as a one-tier ("phones") TextGrid.
void write_phones_textgrid(const std::filesystem::path& path, const PhoneSequence& phones);

// Checks that phones are contiguous (each starts where the last ended, within
// tolerance_s), each has end > start, and throws InputError otherwise.
void check_phone_sequence(const PhoneSequence& phones, const std::string& source_path,
                          double tolerance_s = 1e-6);

}  // namespace avsi
