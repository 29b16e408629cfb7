// `avsi phones`: text (through espeak-ng or Festival) or a recording's
// alignment (TextGrid, HTK .lab, TIMIT .phn, TSV) to a timed phone sequence
// in the project phone set.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "avsi/core/audio.h"
#include "avsi/core/error.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"
#include "avsi/core/tts.h"
#include "command.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

struct PhonesOptions {
    std::string text;
    std::string textgrid;
    std::string lab;
    std::string tsv;
    std::string phn;
    std::string phone_set = "auto";
    std::string lab_units = "auto";
    double sample_rate_hz = 16000.0;
    std::string tier = "phones";
    std::string wav;
    std::string out;
    std::string tts_spec = "espeak:en-us";
    bool tts_given = false;  // --tts was on the command line
    std::string voice;       // the older --voice: an espeak-ng voice
    bool list_voices = false;
    TtsSettings tts;
};

std::string lower_extension(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

int list_voices() {
    for (const auto& [engine, name] : {std::pair{TtsEngine::Espeak, "espeak"}, std::pair{TtsEngine::Festival, "festival"}}) {
        std::vector<std::string> voices;
        try {
            voices = installed_tts_voices(engine);
        } catch (const std::exception& e) {
            log_warning("{}: {}", name, e.what());
        }
        for (const auto& v : voices) std::printf("%s:%s\n", name, v.c_str());
    }
    return ExitSuccess;
}

int run_phones(PhonesOptions o) {
    if (o.list_voices) return list_voices();
    if (o.out.empty()) throw UsageError("--out is required");
    if (!o.voice.empty() && o.tts_given)
        throw UsageError("give --tts or the older --voice (an espeak-ng voice), not both");
    set_tts_voice(o.tts, o.voice.empty() ? o.tts_spec : "espeak:" + o.voice, "--tts");
    const int inputs = int(!o.text.empty()) + int(!o.textgrid.empty()) + int(!o.lab.empty()) + int(!o.tsv.empty()) +
                       int(!o.phn.empty());
    if (inputs != 1)
        throw UsageError("give exactly one input: --text, --textgrid, --lab, --phn or --tsv");
    if (!o.wav.empty() && o.text.empty()) throw UsageError("--wav writes synthesised speech; it needs --text");
    const std::string out_ext = o.out == "-" ? ".tsv" : lower_extension(o.out);
    if (out_ext != ".tsv" && out_ext != ".textgrid")
        throw UsageError(fmt::format("--out {}: unsupported extension '{}'; supported extensions are '.tsv' "
                                     "and '.TextGrid' (or - for TSV on standard output)",
                                     o.out, std::filesystem::path(o.out).extension().string()));
    const auto phone_set = parse_label_phone_set(o.phone_set);  // one_of let only its names through

    PhoneSequence phones;
    if (!o.text.empty()) {
        TtsResult result = synthesize_speech(o.text, o.tts);
        phones = std::move(result.phones);
        if (!o.wav.empty()) {
            write_audio(o.wav, result.audio);
            log_info("wrote {} ({:.3f} s, {} Hz)", o.wav, result.audio.duration_s(), result.audio.sample_rate_hz);
        }
    } else {
        const std::string input = !o.textgrid.empty() ? o.textgrid
                                  : !o.lab.empty()    ? o.lab
                                  : !o.phn.empty()    ? o.phn
                                                      : o.tsv;
        const std::string want = !o.textgrid.empty() ? ".textgrid"
                                 : !o.lab.empty()    ? ".lab"
                                 : !o.phn.empty()    ? ".phn"
                                                     : ".tsv";
        if (lower_extension(input) != want)
            throw UsageError(fmt::format("{} does not end in '{}'", input, want == ".textgrid" ? ".TextGrid" : want));
        LabelReadOptions read_options;
        read_options.tier = o.tier;
        read_options.phone_set = *phone_set;
        read_options.sample_rate_hz = o.sample_rate_hz;
        read_options.lab_unit = o.lab_units == "100ns"     ? LabTimeUnit::HundredNanoseconds
                                : o.lab_units == "seconds" ? LabTimeUnit::Seconds
                                                           : LabTimeUnit::Auto;
        phones = read_phones(input, read_options);
    }
    if (o.out == "-") {
        std::fputs(phones_tsv(phones).c_str(), stdout);  // for `avsi phones … --out - | avsi stream`
        std::fflush(stdout);
        return ExitSuccess;
    }
    if (out_ext == ".tsv") write_phones_tsv(o.out, phones);
    else write_phones_textgrid(o.out, phones);
    log_info("wrote {} ({} phones)", o.out, phones.size());
    return ExitSuccess;
}

const bool registered_phones = register_command({
    "phones",
    "Text or an alignment (TextGrid, .lab, .tsv) to a timed phone sequence",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<PhonesOptions>();
        sub.add_option("--text", o->text, "Text to synthesise (see --tts)")->capture_default_str();
        sub.add_option("--textgrid", o->textgrid, "Praat TextGrid to read phones from (long or short text format)")
            ->capture_default_str();
        sub.add_option("--lab", o->lab,
                       "HTK label file to read phones from (times in 100 ns units; also HTS full-context labels, "
                       "phone- or state-aligned, and MOCHA .lab files in seconds)")
            ->capture_default_str();
        sub.add_option("--phn", o->phn, "TIMIT .phn file to read phones from (sample indices, see --sample-rate)")
            ->capture_default_str();
        sub.add_option("--sample-rate", o->sample_rate_hz, "Sample rate of the .phn sample indices (Hz)")
            ->capture_default_str()
            ->check(CLI::Range(1.0, 1e6));
        sub.add_option("--phone-set", o->phone_set,
                       "Phone set of the labels: auto (project ARPAbet, IPA, Festival, TIMIT; MOCHA when only it "
                       "fits), arpabet, festival, timit or mocha")
            ->capture_default_str()
            ->check(one_of({"auto", "arpabet", "festival", "timit", "mocha"}));
        sub.add_option("--lab-units", o->lab_units,
                       ".lab times: auto (integers 100 ns, decimals seconds), 100ns or seconds")
            ->capture_default_str()
            ->check(one_of({"auto", "100ns", "seconds"}));
        sub.add_option("--tsv", o->tsv, "TSV label file to read phones from (start_s end_s phone)")
            ->capture_default_str();
        sub.add_option("--tier", o->tier, "TextGrid tier holding the phones")->capture_default_str();
        CLI::Option* tts = sub.add_option("--tts", o->tts_spec,
                       "Synthesiser and voice: espeak:<voice> (en-us, en, en-gb-x-rp, ...) or festival:<voice> "
                       "(cmu_us_slt_arctic_hts, kal_diphone); --list-voices shows the installed ones")
            ->capture_default_str();
        sub.add_option("--voice", o->voice, "An espeak-ng voice; the same as --tts espeak:<voice>");
        sub.add_flag("--list-voices", o->list_voices, "List the installed voices as --tts takes them, and exit");
        sub.add_option("--rate", o->tts.rate_wpm, "espeak-ng speaking rate, words per minute (80-450)")
            ->capture_default_str();
        sub.add_option("--pitch", o->tts.pitch, "espeak-ng pitch (0-99)")->capture_default_str();
        sub.add_option("--lead-silence", o->tts.lead_silence_s, "Silence before the speech, seconds")
            ->capture_default_str();
        sub.add_option("--trail-silence", o->tts.trail_silence_s, "Silence after the speech, seconds")
            ->capture_default_str();
        sub.add_option("--wav", o->wav, "Write the synthesised speech here (WAV, with --text)")
            ->capture_default_str();
        sub.add_option("--out", o->out,
                       "Output phones: .tsv (start_s end_s phone) or .TextGrid; - writes the TSV to standard output "
                       "(required)")
            ->capture_default_str();
        return [o, tts] {
            o->tts_given = tts->count() > 0;
            return run_phones(*o);
        };
    }});

}  // namespace
}  // namespace avsi::cli
