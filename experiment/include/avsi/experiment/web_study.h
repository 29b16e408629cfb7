// The online study: the protocol's lists and stimuli as a jsPsych 8 study for
// JATOS (`avsi export-web`), and its results back into the session database
// (`avsi import-web`).
//
// Export writes a self-contained folder (index.html, the vendored jsPsych 8
// library and plugins, avsi's study runtime, study.json with the subjects'
// plans, the stimuli checked against their manifest and transcoded to H.264
// Constrained Baseline + AAC only when they are not already, the screening
// and calibration sounds) that runs from any static web server, and packs the
// same folder as a JATOS study archive (.jzip: one .jas study-properties JSON
// and the study assets folder, JATOS' documented "JATOS Study Archive"
// layout).
//
// Screening (generated here, written as WAV):
//  - antiphase test (Woods, Siegel, Traer & McDermott 2017, "Headphone
//    screening to facilitate web-based auditory experiments", Atten. Percept.
//    Psychophys. 79): three 200 Hz tones, one 6 dB softer, one with the
//    right channel in antiphase (softer over loudspeakers, where the two
//    channels cancel in the air, not over headphones); the task is to pick
//    the softest;
//  - Huggins pitch (Milne, Bianco, Poole, Zhao, Oxenham, Billig & Chait 2021,
//    "An online headphone screening test based on dichotic pitch", Behav.
//    Res. Methods 53): three noises, one with a narrow band (±6 % around
//    600 Hz) whose phase is inverted in one ear, which only over headphones
//    is heard as a faint tone; the task is to pick the noise with the tone.
//  - a calibration noise with the long-term average spectrum of the stimuli'
//    audio at the protocol's speech level, for the comfortable-level step.
//
// Import reads JATOS result exports (data-only text, or the JRZIP results
// archive) and plain jsPsych JSON, validates every record against the design
// (experiment, subject, list, trial order, stimulus SHA-256 against the
// manifest) and stores the trials as online sessions in one transaction.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/protocol.h"
#include "avsi/experiment/timing_certificate.h"

namespace avsi::experiment {

// The protocol's [online] section (docs/protocol-format.md).
struct OnlineSettings {
    std::string completion_url;      // where the end screen sends the participant ("" = nowhere)
    std::string screening_fail_url;  // where a failed screening sends them with on_screening_fail = "end"
    std::string results_url;         // POST endpoint for each record outside JATOS ("" = none)
    std::string jatos_title;         // the JATOS study title ("" = the experiment name)
    bool antiphase = true;           // headphone_check contains "antiphase"
    bool huggins = false;            // headphone_check contains "huggins"
    int antiphase_trials = 6;
    int antiphase_pass = 5;          // correct answers needed
    int huggins_trials = 6;
    int huggins_pass = 5;
    double tone_ms = 1000.0;         // antiphase tone length (Woods et al.: 1000 ms)
    double ramp_ms = 100.0;          // raised-cosine on/off ramps of tones and noises
    double gap_ms = 500.0;           // silence between the three intervals
    double huggins_ms = 1000.0;      // Huggins noise length
    double huggins_hz = 600.0;       // centre of the phase-inverted band
    double huggins_band = 0.06;      // half-width of the band, fraction of the centre (±6 %)
    bool end_on_screening_fail = false;  // on_screening_fail = "end" (else "continue"); failures are recorded either way
    bool level_setting = true;       // the comfortable-level step with calibration noise
    double calibration_s = 4.0;      // calibration noise buffer (looped)
    double preload_timeout_s = 120.0;
    int sample_rate_hz = 44100;      // of the generated sounds
};

// Validates the protocol's [online] section (every problem at once, as
// InputError at the key's line); an absent section gives the defaults.
OnlineSettings read_online_settings(const Protocol& protocol);

// One 3-interval screening sound: stereo, `settings.sample_rate_hz`.
// The antiphase test's tone: 200 Hz at `level_dbfs` RMS (+`gain_db`), ramped;
// `antiphase` inverts the right channel.
Audio antiphase_tone(const OnlineSettings& settings, double level_dbfs, double gain_db, bool antiphase);

// A Huggins-pitch noise (band inverted in the right channel) or, with
// `pitch` false, the same kind of diotic noise; `seed` picks the noise.
Audio huggins_noise(const OnlineSettings& settings, double level_dbfs, bool pitch, std::uint64_t seed);

// Stereo diotic noise of `duration_s` at `out_rate_hz` with the long-term
// average power spectrum of `speech` (mono clips at `speech_rate_hz`, Welch
// estimate with 2048-point Hann frames over the frames within 40 dB of each
// clip's loudest), at `level_dbfs` RMS; periodic, so it loops without a click.
Audio shaped_noise(const std::vector<std::vector<float>>& speech, int speech_rate_hz, double level_dbfs,
                   double duration_s, std::uint64_t seed, int out_rate_hz);

// What a browser needs and what a stimulus file has.
struct MediaProbe {
    std::string container;      // libavformat's format name
    std::string video_codec;    // "h264", …
    std::string video_profile;  // "Constrained Baseline", "High", …
    std::string pixel_format;   // "yuv420p", …
    std::string audio_codec;    // "aac", "" for none
    std::string audio_profile;  // "LC", …
    int width = 0;
    int height = 0;
    // H.264 Constrained Baseline/Baseline yuv420p in MP4, AAC-LC (or no) audio.
    bool browser_ready() const;
    // Why not, for the log ("video h264 High, audio mp3").
    std::string describe() const;
};
// Reads the streams of a media file. Throws InputError naming it.
MediaProbe probe_media(const std::filesystem::path& path);

struct ExportWebSettings {
    std::filesystem::path protocol;
    std::filesystem::path stimuli_dir;  // built by `avsi build-stimuli`: manifest.json + clips
    std::filesystem::path lists;        // lists.csv from `avsi design`
    std::filesystem::path out_dir;      // the study folder
    std::filesystem::path jzip;         // the JATOS archive ("" = <out_dir>.jzip)
    std::filesystem::path web_dir;      // avsi's web/ folder (src/ + node_modules/); "" = the source tree's
};

struct ExportWebResult {
    std::string study_id;
    int subjects = 0;
    int trials = 0;
    int stimuli = 0;
    int transcoded = 0;
    std::filesystem::path jzip;
    std::vector<std::filesystem::path> vendored;  // jsPsych files copied
};

// Writes the study folder and its .jzip. The folder is written beside the
// target and moved into place, so a failed export leaves no half study; an
// existing folder is replaced only if it is an earlier avsi export.
ExportWebResult export_web(const ExportWebSettings& settings);

// Which run to keep of a subject who took the study in more than one
// browser (each browser's localStorage holds its own run, so a second
// browser starts again at trial 1 under a new run id).
enum class RunRule {
    Refuse,        // a subject with two runs is an error naming them (the default)
    First,         // the run that started first
    Last,          // the run that started last
    MostComplete,  // the run with the most trials answered (the earlier on a tie)
    Session,       // the run holding one of `RunChoice::sessions` (browser session ids)
};
struct RunChoice {
    RunRule rule = RunRule::Refuse;
    std::vector<std::string> sessions;  // for RunRule::Session
};
// Parses first|last|most-complete|session=ID[,ID…]; throws UsageError.
RunChoice parse_run_choice(const std::string& text);

struct ImportWebSettings {
    std::vector<std::filesystem::path> results;  // JATOS results (.txt, .jrzip/.zip) or jsPsych JSON
    std::filesystem::path protocol;
    std::filesystem::path database;
    std::filesystem::path stimuli;   // a folder with manifest.json (the stimulus folder or the exported study)
    RunChoice runs;                  // which run of a subject with several to keep
    bool require_complete = false;   // refuse when a subject has fewer trials than the design
};

// A subject's run left out by the run rule.
struct LeftOutRun {
    int subject = 0;
    std::string run;
    std::string kept_run;
    int trials = 0;                     // distinct trials answered in the run left out
    int kept_trials = 0;
    std::string started_utc;
    std::vector<std::string> sessions;  // its browser session ids
};

// A subject with fewer answered trials than the design.
struct IncompleteSubject {
    int subject = 0;
    int answered = 0;
    int planned = 0;
};

struct ImportWebResult {
    int records = 0;            // avsi records read
    int ignored = 0;            // JSON objects that are not avsi records (other plugins' rows)
    int duplicates = 0;         // records read twice (same trial from two sources)
    int subjects = 0;
    int subjects_added = 0;
    int sessions_added = 0;
    int trials_added = 0;
    int trials_present = 0;
    int screening_failed = 0;   // subjects with a failed headphone check (recorded, not excluded)
    std::vector<std::string> notes;  // per subject: answered, complete or not, screening
    std::vector<LeftOutRun> left_out;          // runs not imported (RunChoice)
    std::vector<IncompleteSubject> incomplete;  // subjects with fewer trials than the design
    std::vector<TimingCertificate> timing;      // the imported subjects' timing certificates (whole database rows)
};

// Validates every record of every file, then stores them in one
// transaction. Throws InputError (file:line:col: error: field: …) and leaves
// the database unchanged on any problem: a truncated file, records of
// another experiment or export, a subject's trials out of plan order or not
// matching the design, a stimulus hash not in the manifest, a response that
// contradicts one already stored (answers are compared by their text and
// empty-answer confirmation), a subject with two runs and no run rule, and,
// with `require_complete`, a subject with fewer trials than the design.
ImportWebResult import_web(const ImportWebSettings& settings);

}  // namespace avsi::experiment
