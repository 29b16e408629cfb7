// The protocol's [online] section (see web_study.h, docs/protocol-format.md).
#include <fmt/format.h>

#include "avsi/core/config.h"
#include "avsi/core/error.h"
#include "avsi/experiment/web_study.h"

namespace avsi::experiment {

namespace {

// A URL the browser can follow: absolute http(s) or a path on the same server.
bool plausible_url(const std::string& url) {
    if (url.empty()) return true;
    if (url.find_first_of(" \t\n\r\"<>") != std::string::npos) return false;
    return url.rfind("https://", 0) == 0 || url.rfind("http://", 0) == 0 || url[0] == '/';
}

}  // namespace

OnlineSettings read_online_settings(const Protocol& protocol) {
    const ConfigSection& online = protocol.online;
    DiagnosticList problems;
    OnlineSettings s;
    for (auto [key, target] : {std::pair<const char*, std::string*>{"completion_url", &s.completion_url},
                               {"screening_fail_url", &s.screening_fail_url},
                               {"results_url", &s.results_url}}) {
        *target = online.get_string(key, "", problems);
        if (!plausible_url(*target))
            online.report(key,
                          fmt::format("expected an http(s):// URL or a path starting with '/', without spaces or "
                                      "quotes, got \"{}\"",
                                      *target),
                          problems);
    }
    s.jatos_title = online.get_string("jatos_title", "", problems);
    if (online.has("headphone_check")) {
        const auto tests = online.get_string_list("headphone_check", problems);
        s.antiphase = false;
        s.huggins = false;
        for (const auto& t : tests) {
            if (t == "antiphase") s.antiphase = true;
            else if (t == "huggins") s.huggins = true;
            else {
                std::string message =
                    fmt::format("expected a list of \"antiphase\" and/or \"huggins\" ([] for none), got \"{}\"", t);
                const std::string hint = closest_match(t, {"antiphase", "huggins"});
                if (!hint.empty()) message += fmt::format(" (did you mean \"{}\"?)", hint);
                online.report("headphone_check", message, problems);
            }
        }
    }
    s.antiphase_trials = static_cast<int>(online.get_int("antiphase_trials", s.antiphase_trials, 1, 100, problems));
    s.antiphase_pass = static_cast<int>(online.get_int("antiphase_pass", s.antiphase_pass, 0, 100, problems));
    s.huggins_trials = static_cast<int>(online.get_int("huggins_trials", s.huggins_trials, 1, 100, problems));
    s.huggins_pass = static_cast<int>(online.get_int("huggins_pass", s.huggins_pass, 0, 100, problems));
    if (s.antiphase_pass > s.antiphase_trials)
        online.report("antiphase_pass",
                      fmt::format("expected at most antiphase_trials ({}), got {}", s.antiphase_trials, s.antiphase_pass),
                      problems);
    if (s.huggins_pass > s.huggins_trials)
        online.report("huggins_pass",
                      fmt::format("expected at most huggins_trials ({}), got {}", s.huggins_trials, s.huggins_pass),
                      problems);
    s.tone_ms = online.get_number("tone_ms", s.tone_ms, 100.0, 5000.0, problems);
    s.ramp_ms = online.get_number("ramp_ms", s.ramp_ms, 0.0, 500.0, problems);
    s.gap_ms = online.get_number("gap_ms", s.gap_ms, 0.0, 5000.0, problems);
    s.huggins_ms = online.get_number("huggins_ms", s.huggins_ms, 100.0, 5000.0, problems);
    s.huggins_hz = online.get_number("huggins_hz", s.huggins_hz, 200.0, 2000.0, problems);
    s.huggins_band = online.get_number("huggins_band", s.huggins_band, 0.01, 0.3, problems);
    if (2.0 * s.ramp_ms > std::min(s.tone_ms, s.huggins_ms))
        online.report("ramp_ms",
                      fmt::format("expected at most half of tone_ms and huggins_ms ({} ms), got {}",
                                  std::min(s.tone_ms, s.huggins_ms) / 2.0, s.ramp_ms),
                      problems);
    s.end_on_screening_fail = online.get_choice("on_screening_fail", {"continue", "end"}, "continue", problems) == "end";
    s.level_setting = online.get_bool("level_setting", s.level_setting, problems);
    s.calibration_s = online.get_number("calibration_s", s.calibration_s, 1.0, 30.0, problems);
    s.preload_timeout_s = online.get_number("preload_timeout_s", s.preload_timeout_s, 5.0, 3600.0, problems);
    s.sample_rate_hz = static_cast<int>(online.get_int("sample_rate_hz", s.sample_rate_hz, 22050, 96000, problems));
    online.check_unknown_keys(problems);
    problems.throw_if_any();
    return s;
}

}  // namespace avsi::experiment
