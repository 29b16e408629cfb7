// Time-aligned label files: Praat TextGrid (long and short text formats,
// UTF-8 and UTF-16), HTK .lab (100 ns units; also HTS full-context labels,
// phone- or state-aligned, and MOCHA-TIMIT's .lab in seconds), TIMIT .phn
// (sample indices) and TSV (start end label, in seconds), and their
// conversion to phone sequences in the project phone set. Label symbols may
// be the project's ARPAbet, MFA IPA, Festival's radio set, TIMIT's 61 symbols
// or MOCHA's set (protocols/languages/en/phone_map.tsv; docs/labels.md).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
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

// How .lab times are written.
enum class LabTimeUnit {
    Auto,                // 100 ns when every time is an integer, seconds when any has a decimal point (MOCHA)
    HundredNanoseconds,  // HTK, HTS
    Seconds,             // MOCHA-TIMIT .lab, xwaves-style
};

// HTK label file: "start end label [score]" per line, times in 100 ns units
// (or seconds, see LabTimeUnit). HTS labels come out as written: full
// context and state suffix included (see hts_centre_phone, merge_hts_states).
// `used_unit` (optional) receives the unit Auto chose.
std::vector<Interval> read_htk_lab(const std::filesystem::path& path, LabTimeUnit unit = LabTimeUnit::Auto,
                                   LabTimeUnit* used_unit = nullptr);
// TIMIT .phn: "start end phone" per line, times as sample indices at
// `sample_rate_hz` (16 kHz in TIMIT).
std::vector<Interval> read_timit_phn(const std::filesystem::path& path, double sample_rate_hz = 16000.0);

// The centre phone of an HTS full-context label "p1^p2-p3+p4=p5@…" (p3), and
// its syllable stress from the "/B:b1-…" field when present; nullopt when the
// label is not a full-context label.
struct HtsPhone {
    std::string phone;
    std::optional<bool> stressed;
};
std::optional<HtsPhone> hts_centre_phone(std::string_view label);
// HTS labels: state-aligned lines ("label[2]" … "label[6]") merged into one
// interval per phone, and full-context labels replaced by their centre phone,
// a vowel with the stress digit of its syllable ("ae1", "ax0"). Plain labels
// pass unchanged. A state line that does not
// continue its phone's states, or a full-context label whose centre cannot be
// read, throws InputError naming `source_path` and the line.
std::vector<Interval> merge_hts_labels(const std::vector<Interval>& intervals, const std::string& source_path);

// Checks that label times are plausible for speech: every labelled phone at
// least 5 ms long and the utterance at least 50 ms. `unit` says how the
// file's numbers were read ("100 ns units", "seconds", "samples at 16000 Hz")
// and `seconds_per_unit` their scale; the error names the first implausible
// label (file:line) and the unit the numbers probably are.
void check_label_times(const std::vector<Interval>& intervals, const std::string& source_path,
                       const std::string& unit, double seconds_per_unit);
// TSV: "start_s end_s label" per line (tab or space separated; an optional
// header line "start_s end_s phone" is skipped).
std::vector<Interval> read_label_tsv(const std::filesystem::path& path);

// The phone set of a label file's symbols (protocols/languages/en/phone_map.tsv).
enum class LabelPhoneSet {
    Auto,      // per label: project ARPAbet, MFA IPA, Festival radio, TIMIT (in that
               // order); a file with a label none of these know but whose every label
               // is MOCHA's is read as MOCHA
    Arpabet,   // the project's ARPAbet (AA1, P, sil, sp) and MFA IPA
    Festival,  // Festival's radio set (pau, ax, el, h#)
    Timit,     // TIMIT's 61 symbols (h#, ix, bcl, q)
    Mocha,     // MOCHA-TIMIT's set (sil, breath, @@, ii)
};
// "auto", "arpabet", "festival", "timit", "mocha"; nullopt for anything else.
std::optional<LabelPhoneSet> parse_label_phone_set(std::string_view name);

// Phones from label intervals in the given phone set; empty labels, "sp",
// "sil", "<eps>", pauses and breaths become `sil`. Gaps between intervals are
// filled with `sil`; a symbol with no phone of its own (TIMIT q) lengthens the
// phone before it; a TIMIT closure followed by its release (bcl b, dcl jh)
// is one stop or affricate. Unknown symbols throw InputError naming the file and line/interval.
PhoneSequence phones_from_intervals(const std::vector<Interval>& intervals, const std::string& source_path,
                                    LabelPhoneSet phone_set = LabelPhoneSet::Auto);

struct LabelReadOptions {
    std::string tier = "phones";                     // TextGrid tier holding phones
    LabelPhoneSet phone_set = LabelPhoneSet::Auto;   // the symbols' phone set
    LabTimeUnit lab_unit = LabTimeUnit::Auto;        // .lab times
    double sample_rate_hz = 16000.0;                 // .phn sample indices
};
// Reads phones from a .TextGrid, .lab (HTK, HTS, MOCHA), .phn (TIMIT) or .tsv
// file, chosen by extension, and checks the times (check_label_times).
PhoneSequence read_phones(const std::filesystem::path& path, const LabelReadOptions& options = {});

// Writes phones as TSV ("start_s\tend_s\tphone" with a header line).
void write_phones_tsv(const std::filesystem::path& path, const PhoneSequence& phones);
// The same TSV as text (for standard output: `avsi phones --out -`).
std::string phones_tsv(const PhoneSequence& phones);
// Writes phones as a one-tier ("phones") TextGrid.
void write_phones_textgrid(const std::filesystem::path& path, const PhoneSequence& phones);

// Checks that phones are contiguous (each starts where the last ended, within
// tolerance_s), each has end > start, and throws InputError otherwise.
void check_phone_sequence(const PhoneSequence& phones, const std::string& source_path,
                          double tolerance_s = 1e-6);

}  // namespace avsi
