// The analysis report: anova.json first, then HTML, Markdown and CSVs drawn
// from the same JSON values, so every number shown equals the one stored.
#include "avsi/analysis/report.h"
#include "avsi/analysis/methods_report.h"
#include "avsi/analysis/timing_report.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <cstdio>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"
#include "report_html.h"
#include "report_plot.h"

namespace avsi::analysis {

using nlohmann::json;

namespace detail {

std::string base64(std::string_view bytes) {
    static const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    std::size_t i = 0;
    for (; i + 2 < bytes.size(); i += 3) {
        const unsigned v = (unsigned(static_cast<unsigned char>(bytes[i])) << 16) |
                           (unsigned(static_cast<unsigned char>(bytes[i + 1])) << 8) |
                           unsigned(static_cast<unsigned char>(bytes[i + 2]));
        for (int s = 18; s >= 0; s -= 6) out += alphabet[(v >> s) & 63];
    }
    if (i < bytes.size()) {
        unsigned v = unsigned(static_cast<unsigned char>(bytes[i])) << 16;
        if (i + 1 < bytes.size()) v |= unsigned(static_cast<unsigned char>(bytes[i + 1])) << 8;
        out += alphabet[(v >> 18) & 63];
        out += alphabet[(v >> 12) & 63];
        out += i + 1 < bytes.size() ? alphabet[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

void append_to_report(const std::filesystem::path& out_dir, const std::string& md, const std::string& html) {
    const std::filesystem::path md_path = out_dir / "report.md", html_path = out_dir / "index.html";
    if (!md.empty() && std::filesystem::exists(md_path)) write_text_file(md_path, read_text_file(md_path) + md);
    std::string page = read_text_file(html_path);
    const auto body = page.rfind("</body>");
    if (body == std::string::npos)
        page += html;
    else
        page.insert(body, html);
    write_text_file(html_path, page);
}

}  // namespace detail

AnalysisResult analyze(const WithinData& data, double confidence) {
    AnalysisResult r;
    r.data = data;
    r.anova = rm_anova(data);
    r.pairwise = pairwise_comparisons(data, r.anova, PairwiseSettings{confidence});
    r.descriptives = describe(data, confidence);
    return r;
}

namespace {

// ".27" style: no leading zero for quantities bounded by 1.
std::string no_leading_zero(std::string s) {
    if (s.rfind("0.", 0) == 0) return s.substr(1);
    if (s.rfind("-0.", 0) == 0) return "-" + s.substr(2);
    return s;
}

std::string df_text(double df) {
    return std::fabs(df - std::round(df)) < 1e-9 ? fmt::format("{:.0f}", df) : fmt::format("{:.2f}", df);
}

json opt(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

}  // namespace

std::string apa_p(double p) {
    if (p < 0.001) return "p < .001";
    return "p = " + no_leading_zero(fmt::format("{:.3f}", p));
}

std::string table_p(double p) {
    if (p == 0.0) return "0";
    if (p < 1e-4) return fmt::format("{:.2e}", p);
    return fmt::format("{:.4f}", p);
}

std::string apa_anova(const AnovaResult& a) {
    const std::string dfs = fmt::format("F({}, {})", df_text(a.df_conditions), df_text(a.df_error));
    if (!a.F) return dfs + " not defined (no error variance)";
    return fmt::format("{} = {:.2f}, {}, ηp² = {}", dfs, *a.F, apa_p(*a.p_value),
                       no_leading_zero(fmt::format("{:.2f}", a.partial_eta_sq)));
}

namespace {

json correction_json(const Correction& c) {
    return {{"epsilon", opt(c.epsilon)},
            {"df_conditions", c.df_conditions},
            {"df_error", c.df_error},
            {"p", opt(c.p_value)}};
}

std::string sphericity_sentence(const AnovaResult& a) {
    std::string s;
    if (a.k == 2) {
        s = "With two conditions sphericity holds trivially (W = 1, ε = 1).";
    } else if (!a.mauchly.computable) {
        s = a.mauchly.note + ".";
    } else {
        s = fmt::format("Mauchly's test: W = {}, χ²({}) = {:.2f}, {}.",
                        no_leading_zero(fmt::format("{:.3f}", a.mauchly.W)), df_text(*a.mauchly.df), *a.mauchly.chisq,
                        apa_p(*a.mauchly.p_value));
    }
    if (a.k > 2 && a.greenhouse_geisser.epsilon && a.greenhouse_geisser.p_value) {
        s += fmt::format(" Greenhouse-Geisser ε = {}, F({}, {}), {}; ",
                         no_leading_zero(fmt::format("{:.3f}", *a.greenhouse_geisser.epsilon)),
                         df_text(a.greenhouse_geisser.df_conditions), df_text(a.greenhouse_geisser.df_error),
                         apa_p(*a.greenhouse_geisser.p_value));
        if (a.huynh_feldt.epsilon && a.huynh_feldt.p_value)
            s += fmt::format("Huynh-Feldt ε = {}{}, {}.", fmt::format("{:.3f}", *a.huynh_feldt.epsilon),
                             *a.huynh_feldt.epsilon > 1 ? " (treated as 1)" : "", apa_p(*a.huynh_feldt.p_value));
        else
            s += fmt::format("Huynh-Feldt ε not estimable with n = {}.", a.n);
    }
    return s;
}

json result_json(const AnalysisResult& r, const ReportSettings& settings) {
    const AnovaResult& a = r.anova;
    json dropped = json::array();
    for (const auto& d : a.dropped) dropped.push_back({{"subject", d.subject}, {"missing", d.missing_conditions}});
    json pairs = json::array();
    for (const auto& c : r.pairwise)
        pairs.push_back({{"a", c.a},
                         {"b", c.b},
                         {"mean_difference", c.mean_difference},
                         {"sd_difference", c.sd_difference},
                         {"ci_low", c.ci_low},
                         {"ci_high", c.ci_high},
                         {"d_z", opt(c.d_z)},
                         {"t", opt(c.t)},
                         {"df", c.df},
                         {"p", opt(c.p_value)},
                         {"p_holm", opt(c.p_holm)},
                         {"p_bonferroni", opt(c.p_bonferroni)},
                         {"t_pooled", opt(c.t_pooled)},
                         {"df_pooled", c.df_pooled},
                         {"p_pooled", opt(c.p_pooled)},
                         {"p_pooled_holm", opt(c.p_pooled_holm)},
                         {"p_pooled_bonferroni", opt(c.p_pooled_bonferroni)},
                         {"ci_pooled_low", c.ci_pooled_low},
                         {"ci_pooled_high", c.ci_pooled_high}});
    json desc = json::array();
    for (const auto& d : r.descriptives)
        desc.push_back({{"condition", d.condition},
                        {"n", d.n},
                        {"mean", d.mean},
                        {"sd", d.sd},
                        {"se_within", d.se_within},
                        {"ci_low", d.ci_low},
                        {"ci_high", d.ci_high}});
    return {
        {"generated_by", "avsi 0.1.0 analyze"},
        {"source", settings.source.string()},
        {"rule_set", settings.rule_set},
        {"dependent_variable", settings.dv},
        {"confidence", settings.confidence},
        {"design", {{"subjects", a.n}, {"conditions", r.data.conditions}, {"dropped_subjects", dropped}}},
        {"anova",
         {{"ss_conditions", a.ss_conditions},
          {"ss_subjects", a.ss_subjects},
          {"ss_error", a.ss_error},
          {"df_conditions", a.df_conditions},
          {"df_subjects", a.df_subjects},
          {"df_error", a.df_error},
          {"ms_conditions", a.ms_conditions},
          {"ms_error", a.ms_error},
          {"F", opt(a.F)},
          {"p", opt(a.p_value)},
          {"partial_eta_squared", a.partial_eta_sq},
          {"generalized_eta_squared", a.generalized_eta_sq}}},
        {"sphericity",
         {{"mauchly",
           {{"computable", a.mauchly.computable},
            {"W", a.mauchly.W},
            {"chisq", opt(a.mauchly.chisq)},
            {"df", opt(a.mauchly.df)},
            {"p", opt(a.mauchly.p_value)},
            {"note", a.mauchly.note}}},
          {"greenhouse_geisser", correction_json(a.greenhouse_geisser)},
          {"huynh_feldt", correction_json(a.huynh_feldt)},
          {"lower_bound", correction_json(a.lower_bound)}}},
        {"apa", apa_anova(a)},
        {"sphericity_text", sphericity_sentence(a)},
        {"pairwise", pairs},
        {"descriptives", desc},
        {"notes", a.notes},
    };
}

using detail::base64;

// How a number is shown; the stored value is always the JSON one.
enum class Show { Fixed2, Fixed3, Fixed4, P, Df, Int };

std::string show(const json& v, Show how) {
    if (v.is_null()) return "–";
    const double x = v.get<double>();
    switch (how) {
    case Show::Fixed2: return fmt::format("{:.2f}", x);
    case Show::Fixed3: return fmt::format("{:.3f}", x);
    case Show::Fixed4: return fmt::format("{:.4f}", x);
    case Show::P: return table_p(x);
    case Show::Df: return df_text(x);
    case Show::Int: return fmt::format("{:.0f}", x);
    }
    return "";
}

// A table cell carrying the JSON pointer and exact value of what it shows.
std::string cell(const json& doc, const std::string& pointer, Show how) {
    const json& v = doc.at(json::json_pointer(pointer));
    return fmt::format("<td data-key=\"{}\" data-value=\"{}\">{}</td>", pointer, v.dump(), show(v, how));
}

const char* kCss = R"(body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;max-width:60rem;margin:2rem auto;padding:0 1rem;color:#222;line-height:1.45}
h1{font-size:1.6rem}h2{font-size:1.2rem;margin-top:2rem;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:0.5rem 0;font-size:0.92rem}
th,td{border:1px solid #ccc;padding:0.25rem 0.6rem;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
.apa{font-size:1.1rem;background:#f6f8fa;padding:0.6rem 1rem;border-left:4px solid #58c}
.note{color:#555;font-size:0.9rem}img{max-width:100%;height:auto})";

// Which keyword-scoring rule set produced the scores, for the report.
std::string scoring_sentence(const std::string& rule_set) {
    if (rule_set.empty()) return "Keyword scoring rule set: not recorded in the scores file.";
    return fmt::format("Keywords scored with the {} rule set (avsi score; see docs/scoring.md).", rule_set);
}

// The Sphericity section (heading, sentence, Mauchly and correction tables) of the HTML page.
std::string sphericity_html_section(const json& doc) {
    std::string h;
    h += "<h2>Sphericity</h2>\n<p>" + xml_escape(doc["sphericity_text"].get<std::string>()) + "</p>\n";
    h += "<table>\n<tr><th>Mauchly's test</th><th>W</th><th>χ²</th><th>df</th><th>p</th></tr>\n";
    h += "<tr><td>condition</td>" + cell(doc, "/sphericity/mauchly/W", Show::Fixed4) +
         cell(doc, "/sphericity/mauchly/chisq", Show::Fixed2) + cell(doc, "/sphericity/mauchly/df", Show::Df) +
         cell(doc, "/sphericity/mauchly/p", Show::P) + "</tr>\n</table>\n";
    h += "<table>\n<tr><th>Correction</th><th>ε</th><th>df (condition)</th><th>df (error)</th><th>p</th></tr>\n";
    for (const auto& [key, name] : {std::pair{"greenhouse_geisser", "Greenhouse-Geisser"},
                                    std::pair{"huynh_feldt", "Huynh-Feldt (raw ε; min(1, ε) used)"},
                                    std::pair{"lower_bound", "Lower bound 1/(k−1)"}}) {
        const std::string base = std::string("/sphericity/") + key;
        h += std::string("<tr><td>") + xml_escape(name) + "</td>" + cell(doc, base + "/epsilon", Show::Fixed4) +
             cell(doc, base + "/df_conditions", Show::Df) + cell(doc, base + "/df_error", Show::Df) +
             cell(doc, base + "/p", Show::P) + "</tr>\n";
    }
    h += "</table>\n";
    return h;
}

std::string build_html(const json& doc, const std::string& png_base64) {
    std::string h;
    h += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n";
    h += "<title>" + xml_escape(doc["title"].get<std::string>()) + "</title>\n";
    h += std::string("<style>") + kCss + "</style>\n</head>\n<body>\n";
    h += "<h1>" + xml_escape(doc["title"].get<std::string>()) + "</h1>\n";
    h += fmt::format("<p class=\"note\">Source: {}. {} subjects × {} conditions in the analysis. Generated by {}.</p>\n",
                     xml_escape(doc["source"].get<std::string>()), doc["design"]["subjects"].get<std::size_t>(),
                     doc["design"]["conditions"].size(), xml_escape(doc["generated_by"].get<std::string>()));
    h += "<p class=\"note\">" + xml_escape(scoring_sentence(doc["rule_set"].get<std::string>())) + "</p>\n";
    for (const auto& d : doc["design"]["dropped_subjects"])
        h += fmt::format("<p class=\"note\">Subject {} was dropped listwise (no score in: {}).</p>\n",
                         xml_escape(d["subject"].get<std::string>()),
                         xml_escape(fmt::format("{}", fmt::join(d["missing"].get<std::vector<std::string>>(), ", "))));

    h += "<h2>Repeated-measures ANOVA</h2>\n";
    h += "<p class=\"apa\" data-key=\"/apa\">" + xml_escape(doc["apa"].get<std::string>()) + "</p>\n";
    h += "<table>\n<tr><th>Source</th><th>SS</th><th>df</th><th>MS</th><th>F</th><th>p</th><th>ηp²</th><th>ηG²</th></tr>\n";
    h += "<tr><td>Condition</td>" + cell(doc, "/anova/ss_conditions", Show::Fixed2) +
         cell(doc, "/anova/df_conditions", Show::Df) + cell(doc, "/anova/ms_conditions", Show::Fixed2) +
         cell(doc, "/anova/F", Show::Fixed2) + cell(doc, "/anova/p", Show::P) +
         cell(doc, "/anova/partial_eta_squared", Show::Fixed3) +
         cell(doc, "/anova/generalized_eta_squared", Show::Fixed3) + "</tr>\n";
    h += "<tr><td>Subjects</td>" + cell(doc, "/anova/ss_subjects", Show::Fixed2) +
         cell(doc, "/anova/df_subjects", Show::Df) + "<td></td><td></td><td></td><td></td><td></td></tr>\n";
    h += "<tr><td>Error</td>" + cell(doc, "/anova/ss_error", Show::Fixed2) + cell(doc, "/anova/df_error", Show::Df) +
         cell(doc, "/anova/ms_error", Show::Fixed2) + "<td></td><td></td><td></td><td></td></tr>\n</table>\n";

    h += sphericity_html_section(doc);

    h += "<h2>Descriptives</h2>\n<table>\n<tr><th>Condition</th><th>n</th><th>Mean %</th><th>SD</th>"
         "<th>SE (within)</th><th>CI low</th><th>CI high</th></tr>\n";
    for (std::size_t j = 0; j < doc["descriptives"].size(); ++j) {
        const std::string b = fmt::format("/descriptives/{}", j);
        h += "<tr><td>" + xml_escape(doc["descriptives"][j]["condition"].get<std::string>()) + "</td>" +
             cell(doc, b + "/n", Show::Int) + cell(doc, b + "/mean", Show::Fixed2) + cell(doc, b + "/sd", Show::Fixed2) +
             cell(doc, b + "/se_within", Show::Fixed2) + cell(doc, b + "/ci_low", Show::Fixed2) +
             cell(doc, b + "/ci_high", Show::Fixed2) + "</tr>\n";
    }
    h += fmt::format("</table>\n<p class=\"note\">Confidence intervals: {:.0f} % within-subject (Cousineau-Morey).</p>\n",
                     100.0 * doc["confidence"].get<double>());
    h += "<img alt=\"Percent correct by condition with within-subject confidence intervals\" "
         "src=\"data:image/png;base64," + png_base64 + "\"/>\n";

    h += "<h2>Pairwise comparisons</h2>\n<p class=\"note\">Fisher's LSD as in the reference study: uncorrected "
         "paired t-tests (df = n − 1), with Holm and Bonferroni adjusted p; the pooled-error LSD uses MS<sub>error</sub> "
         "of the ANOVA (df = error df). Differences are first minus second condition.</p>\n";
    h += "<table>\n<tr><th>Pair</th><th>Diff</th><th>CI low</th><th>CI high</th><th>d<sub>z</sub></th><th>t</th>"
         "<th>df</th><th>p (LSD)</th><th>p Holm</th><th>p Bonf.</th><th>t pooled</th><th>p pooled</th></tr>\n";
    for (std::size_t i = 0; i < doc["pairwise"].size(); ++i) {
        const std::string b = fmt::format("/pairwise/{}", i);
        const auto& pr = doc["pairwise"][i];
        h += "<tr><td>" + xml_escape(pr["a"].get<std::string>() + " − " + pr["b"].get<std::string>()) + "</td>" +
             cell(doc, b + "/mean_difference", Show::Fixed2) + cell(doc, b + "/ci_low", Show::Fixed2) +
             cell(doc, b + "/ci_high", Show::Fixed2) + cell(doc, b + "/d_z", Show::Fixed2) +
             cell(doc, b + "/t", Show::Fixed2) + cell(doc, b + "/df", Show::Df) + cell(doc, b + "/p", Show::P) +
             cell(doc, b + "/p_holm", Show::P) + cell(doc, b + "/p_bonferroni", Show::P) +
             cell(doc, b + "/t_pooled", Show::Fixed2) + cell(doc, b + "/p_pooled", Show::P) + "</tr>\n";
    }
    h += "</table>\n";
    if (!doc["notes"].empty()) {
        h += "<h2>Notes</h2>\n<ul>\n";
        for (const auto& n : doc["notes"]) h += "<li>" + xml_escape(n.get<std::string>()) + "</li>\n";
        h += "</ul>\n";
    }
    h += "<p class=\"note\">Files beside this page: anova.json (all numbers at full precision), pairwise.csv, "
         "descriptives.csv, plot.png, plot.svg, report.md, glmer.R (keyword-level mixed-effects logistic model).</p>\n";
    h += "</body>\n</html>\n";
    return h;
}

std::string md_cell(const json& doc, const std::string& pointer, Show how) {
    return show(doc.at(json::json_pointer(pointer)), how);
}

// The Sphericity section of report.md.
std::string sphericity_md_section(const json& doc) {
    std::string m;
    m += "## Sphericity\n\n" + doc["sphericity_text"].get<std::string>() + "\n\n";
    m += "| Correction | ε | df (condition) | df (error) | p |\n|---|---:|---:|---:|---:|\n";
    for (const auto& [key, name] : {std::pair{"greenhouse_geisser", "Greenhouse-Geisser"},
                                    std::pair{"huynh_feldt", "Huynh-Feldt (raw ε; min(1, ε) used)"},
                                    std::pair{"lower_bound", "Lower bound"}}) {
        const std::string b = std::string("/sphericity/") + key;
        m += std::string("| ") + name + " | " + md_cell(doc, b + "/epsilon", Show::Fixed4) + " | " +
             md_cell(doc, b + "/df_conditions", Show::Df) + " | " + md_cell(doc, b + "/df_error", Show::Df) + " | " +
             md_cell(doc, b + "/p", Show::P) + " |\n";
    }
    return m;
}

std::string build_markdown(const json& doc) {
    std::string m = "# " + doc["title"].get<std::string>() + "\n\n";
    m += fmt::format("Source: `{}`. {} subjects × {} conditions in the analysis.\n\n", doc["source"].get<std::string>(),
                     doc["design"]["subjects"].get<std::size_t>(), doc["design"]["conditions"].size());
    m += scoring_sentence(doc["rule_set"].get<std::string>()) + "\n\n";
    m += "## Repeated-measures ANOVA\n\n**" + doc["apa"].get<std::string>() + "**\n\n";
    m += "| Source | SS | df | MS | F | p | ηp² | ηG² |\n|---|---:|---:|---:|---:|---:|---:|---:|\n";
    m += "| Condition | " + md_cell(doc, "/anova/ss_conditions", Show::Fixed2) + " | " +
         md_cell(doc, "/anova/df_conditions", Show::Df) + " | " + md_cell(doc, "/anova/ms_conditions", Show::Fixed2) +
         " | " + md_cell(doc, "/anova/F", Show::Fixed2) + " | " + md_cell(doc, "/anova/p", Show::P) + " | " +
         md_cell(doc, "/anova/partial_eta_squared", Show::Fixed3) + " | " +
         md_cell(doc, "/anova/generalized_eta_squared", Show::Fixed3) + " |\n";
    m += "| Subjects | " + md_cell(doc, "/anova/ss_subjects", Show::Fixed2) + " | " +
         md_cell(doc, "/anova/df_subjects", Show::Df) + " | | | | | |\n";
    m += "| Error | " + md_cell(doc, "/anova/ss_error", Show::Fixed2) + " | " + md_cell(doc, "/anova/df_error", Show::Df) +
         " | " + md_cell(doc, "/anova/ms_error", Show::Fixed2) + " | | | | |\n\n";
    m += sphericity_md_section(doc);
    m += fmt::format("\n## Descriptives\n\nMeans with {:.0f} % within-subject CIs (Cousineau-Morey).\n\n",
                     100.0 * doc["confidence"].get<double>());
    m += "| Condition | n | Mean % | SD | SE (within) | CI low | CI high |\n|---|---:|---:|---:|---:|---:|---:|\n";
    for (std::size_t j = 0; j < doc["descriptives"].size(); ++j) {
        const std::string b = fmt::format("/descriptives/{}", j);
        m += "| " + doc["descriptives"][j]["condition"].get<std::string>() + " | " + md_cell(doc, b + "/n", Show::Int) +
             " | " + md_cell(doc, b + "/mean", Show::Fixed2) + " | " + md_cell(doc, b + "/sd", Show::Fixed2) + " | " +
             md_cell(doc, b + "/se_within", Show::Fixed2) + " | " + md_cell(doc, b + "/ci_low", Show::Fixed2) + " | " +
             md_cell(doc, b + "/ci_high", Show::Fixed2) + " |\n";
    }
    m += "\n![Percent correct by condition](plot.png)\n\n## Pairwise comparisons\n\n"
         "Fisher's LSD (uncorrected paired t-tests, df = n − 1) with Holm and Bonferroni adjusted p; pooled-error LSD "
         "with the ANOVA's MS_error.\n\n";
    m += "| Pair | Diff | CI low | CI high | d_z | t | df | p (LSD) | p Holm | p Bonf. | t pooled | p pooled |\n"
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (std::size_t i = 0; i < doc["pairwise"].size(); ++i) {
        const std::string b = fmt::format("/pairwise/{}", i);
        const auto& pr = doc["pairwise"][i];
        m += "| " + pr["a"].get<std::string>() + " − " + pr["b"].get<std::string>();
        for (const auto& [key, how] : {std::pair{"mean_difference", Show::Fixed2}, std::pair{"ci_low", Show::Fixed2},
                                       std::pair{"ci_high", Show::Fixed2}, std::pair{"d_z", Show::Fixed2},
                                       std::pair{"t", Show::Fixed2}, std::pair{"df", Show::Df}, std::pair{"p", Show::P},
                                       std::pair{"p_holm", Show::P}, std::pair{"p_bonferroni", Show::P},
                                       std::pair{"t_pooled", Show::Fixed2}, std::pair{"p_pooled", Show::P}})
            m += " | " + md_cell(doc, b + "/" + key, how);
        m += " |\n";
    }
    if (!doc["notes"].empty()) {
        m += "\n## Notes\n\n";
        for (const auto& n : doc["notes"]) m += "- " + n.get<std::string>() + "\n";
    }
    return m;
}

std::string num_or_na(const std::optional<double>& v) { return v ? fmt::format("{}", *v) : "NA"; }

std::string pairwise_csv(const std::vector<PairwiseComparison>& pairs) {
    std::string out = csv_line({"a", "b", "mean_difference", "sd_difference", "ci_low", "ci_high", "d_z", "t", "df",
                                "p", "p_holm", "p_bonferroni", "t_pooled", "df_pooled", "p_pooled", "p_pooled_holm",
                                "p_pooled_bonferroni", "ci_pooled_low", "ci_pooled_high"});
    for (const auto& c : pairs)
        out += csv_line({c.a, c.b, fmt::format("{}", c.mean_difference), fmt::format("{}", c.sd_difference),
                         fmt::format("{}", c.ci_low), fmt::format("{}", c.ci_high), num_or_na(c.d_z), num_or_na(c.t),
                         fmt::format("{}", c.df), num_or_na(c.p_value), num_or_na(c.p_holm),
                         num_or_na(c.p_bonferroni), num_or_na(c.t_pooled), fmt::format("{}", c.df_pooled),
                         num_or_na(c.p_pooled), num_or_na(c.p_pooled_holm), num_or_na(c.p_pooled_bonferroni),
                         fmt::format("{}", c.ci_pooled_low), fmt::format("{}", c.ci_pooled_high)});
    return out;
}

std::string descriptives_csv(const std::vector<ConditionSummary>& rows) {
    std::string out = csv_line({"condition", "n", "mean", "sd", "se_within", "ci_low", "ci_high"});
    for (const auto& d : rows)
        out += csv_line({d.condition, std::to_string(d.n), fmt::format("{}", d.mean), fmt::format("{}", d.sd),
                         fmt::format("{}", d.se_within), fmt::format("{}", d.ci_low), fmt::format("{}", d.ci_high)});
    return out;
}

std::string r_string(const std::string& s) {
    std::string out = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') out += '\\';
        out += c;
    }
    return out + "\"";
}

std::string glmer_script(const std::vector<std::string>& conditions, const std::filesystem::path& keywords) {
    std::string levels;
    for (const auto& c : conditions) levels += (levels.empty() ? "" : ", ") + r_string(c);
    return fmt::format(
        R"(# Keyword-level mixed-effects logistic regression, written by `avsi analyze`.
# Each row of keywords.csv is one keyword of one trial (correct = 0/1).
#   Rscript glmer.R [path/to/keywords.csv]
# Needs R with lme4 (Debian: r-cran-lme4); uses car and emmeans when present.
args <- commandArgs(trailingOnly = TRUE)
path <- if (length(args) >= 1) args[1] else {keywords}
suppressPackageStartupMessages(library(lme4))
d <- read.csv(path, stringsAsFactors = FALSE)
d <- d[!is.na(d$correct), ]
d$condition <- factor(d$condition, levels = c({levels}))
d$subject <- factor(d$subject)
d$sentence <- factor(d$sentence)
m <- glmer(correct ~ condition + (1 | subject) + (1 | sentence), data = d, family = binomial,
           control = glmerControl(optimizer = "bobyqa"))
print(summary(m))
if (requireNamespace("car", quietly = TRUE)) print(car::Anova(m, type = 2))
if (requireNamespace("emmeans", quietly = TRUE)) {{
  em <- emmeans::emmeans(m, ~condition, type = "response")
  print(em)
  print(pairs(em, adjust = "holm"))
}}
)",
        fmt::arg("keywords", r_string(keywords.string())), fmt::arg("levels", levels));
}

}  // namespace

std::string anova_json(const AnalysisResult& result, const ReportSettings& settings) {
    json doc = result_json(result, settings);
    doc["title"] = settings.title;
    return doc.dump(2) + "\n";
}

std::string sphericity_markdown(const AnalysisResult& result) {
    return sphericity_md_section(result_json(result, ReportSettings{}));
}

std::string sphericity_html(const AnalysisResult& result) {
    return sphericity_html_section(result_json(result, ReportSettings{}));
}

void write_report(const AnalysisResult& result, const ReportSettings& settings) {
    namespace fs = std::filesystem;
    fs::create_directories(settings.out_dir);
    json doc = result_json(result, settings);
    doc["title"] = settings.title;
    write_text_file(settings.out_dir / "anova.json", doc.dump(2) + "\n");
    write_text_file(settings.out_dir / "pairwise.csv", pairwise_csv(result.pairwise));
    write_text_file(settings.out_dir / "descriptives.csv", descriptives_csv(result.descriptives));

    detail::PlotData plot;
    for (const auto& d : result.descriptives) {
        plot.conditions.push_back(d.condition);
        plot.means.push_back(d.mean);
        plot.ci_low.push_back(d.ci_low);
        plot.ci_high.push_back(d.ci_high);
    }
    plot.title = settings.title;
    if (settings.dv != "percent") {
        // Any other dependent variable: its name on the axis, the range of the intervals.
        plot.y_label = settings.dv;
        double lo = 0.0, hi = 0.0;
        for (std::size_t j = 0; j < plot.means.size(); ++j) {
            lo = std::min({lo, plot.ci_low[j], plot.means[j]});
            hi = std::max({hi, plot.ci_high[j], plot.means[j]});
        }
        const double pad = 0.05 * std::max(hi - lo, 1e-9);
        plot.y_min = lo < 0.0 ? lo - pad : 0.0;
        plot.y_max = hi > 0.0 ? hi + pad : 0.0;
    }
    plot.caption = fmt::format("n = {} subjects; error bars: {:.0f} % within-subject CI (Cousineau-Morey). {}",
                               result.anova.n, 100.0 * settings.confidence, apa_anova(result.anova));
    {
        AtomicFile png(settings.out_dir / "plot.png");
        detail::write_plot_png(png.temp_path(), plot);
        png.commit();
        AtomicFile svg(settings.out_dir / "plot.svg");
        detail::write_plot_svg(svg.temp_path(), plot);
        svg.commit();
    }
    const std::string png_bytes = read_text_file(settings.out_dir / "plot.png");
    write_text_file(settings.out_dir / "index.html", build_html(doc, base64(png_bytes)));
    write_text_file(settings.out_dir / "report.md", build_markdown(doc));

    fs::path keywords = settings.keywords_csv;
    if (keywords.empty()) keywords = settings.source.parent_path() / "keywords.csv";
    if (!fs::exists(keywords))
        log_warning("{} not found: glmer.R will need the keywords.csv path as its argument", keywords.string());
    else
        keywords = fs::absolute(keywords);
    write_text_file(settings.out_dir / "glmer.R", glmer_script(result.data.conditions, keywords));
    log_info("report written to {}: {}", settings.out_dir.string(), apa_anova(result.anova));
}

void write_pilot_report(const Scores& scores, const ReportSettings& settings, std::size_t complete_subjects) {
    struct Row {
        std::string condition;
        std::set<std::string> subjects;
        long keywords = 0, correct = 0;
        bool counts = true;          // every cell had keyword counts
        double percent_sum = 0.0;    // for cells with only a percent
    };
    std::vector<Row> rows;
    std::set<std::string> subjects;
    for (const auto& c : scores.cells) {
        if (!c.percent) continue;
        auto it = std::find_if(rows.begin(), rows.end(), [&](const Row& r) { return r.condition == c.condition; });
        if (it == rows.end()) it = rows.insert(rows.end(), Row{c.condition, {}, 0, 0, true, 0.0});
        it->subjects.insert(c.subject);
        subjects.insert(c.subject);
        it->keywords += c.keywords;
        it->correct += c.correct;
        if (c.keywords == 0) it->counts = false;
        it->percent_sum += *c.percent;
    }
    const auto percent = [](const Row& r) {
        return r.counts ? 100.0 * static_cast<double>(r.correct) / static_cast<double>(r.keywords)
                        : r.percent_sum / static_cast<double>(r.subjects.size());
    };
    const std::string why = fmt::format(
        "No repeated-measures ANOVA: it needs at least 2 subjects with a score in every condition, and {} has {} "
        "({} subject{} in all). This is a dry run or pilot; the table describes it.",
        settings.source.filename().string(), complete_subjects, subjects.size(), subjects.size() == 1 ? "" : "s");

    std::string csv = csv_line({"condition", "subjects", "keywords", "correct", "percent"});
    std::string md = fmt::format("# {}\n\nSource: `{}`\n\n{}\n\n{}\n\n| condition | subjects | keywords | correct | "
                                 "percent correct |\n| --- | ---: | ---: | ---: | ---: |\n",
                                 settings.title, settings.source.string(), scoring_sentence(settings.rule_set), why);
    std::string table;
    for (const auto& r : rows) {
        const std::string kw = r.counts ? std::to_string(r.keywords) : "NA";
        const std::string ok = r.counts ? std::to_string(r.correct) : "NA";
        csv += csv_line({r.condition, std::to_string(r.subjects.size()), kw, ok, fmt::format("{}", percent(r))});
        md += fmt::format("| {} | {} | {} | {} | {:.1f} |\n", r.condition, r.subjects.size(), kw, ok, percent(r));
        table += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.1f}</td></tr>\n",
                             xml_escape(r.condition), r.subjects.size(), kw, ok, percent(r));
    }
    const std::string html = fmt::format(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0}</title><style>{1}</style>"
        "</head><body>\n<h1>{0}</h1>\n<p>Source: <code>{2}</code></p>\n<p>{5}</p>\n<p>{3}</p>\n<table>\n<tr><th>condition</th>"
        "<th>subjects</th><th>keywords</th><th>correct</th><th>percent correct</th></tr>\n{4}</table>\n</body></html>\n",
        xml_escape(settings.title), kCss, xml_escape(settings.source.string()), xml_escape(why), table,
        xml_escape(scoring_sentence(settings.rule_set)));

    std::filesystem::create_directories(settings.out_dir);
    write_text_file(settings.out_dir / "descriptives.csv", csv);
    write_text_file(settings.out_dir / "report.md", md);
    write_text_file(settings.out_dir / "index.html", html);
    log_info("pilot report written to {}", settings.out_dir.string());
}

std::optional<AnalysisResult> analyze_file(const AnalyzeSettings& s) {
    std::ifstream in(s.input, std::ios::binary);
    if (!in) throw InputError(s.input, "cannot open the scores file");
    char magic[16] = {};
    in.read(magic, 16);
    if (in.gcount() == 16 && std::string_view(magic, 15) == "SQLite format 3")
        throw InputError(s.input,
                         "this is an SQLite session database; `avsi analyze` reads scores. Run `avsi export "
                         "<db> --out DIR` to get responses.csv, then `avsi score --corpus sentences.csv --responses "
                         "DIR/responses.csv --out DIR`, then `avsi analyze DIR/scores.csv --out report/`");
    in.close();
    Scores scores = select_conditions(read_scores(s.input, s.dv), s.conditions, s.conditions_source);
    std::vector<TimingCertificateRow> timing;
    std::vector<std::string> timing_excluded;
    if (!s.timing_certificate.empty()) timing = read_timing_certificates(s.timing_certificate);
    if (s.exclude_timing_fail) {
        if (s.timing_certificate.empty())
            throw UsageError("--exclude-timing-fail: give the timing certificates with --timing-certificate");
        scores = exclude_timing_failures(scores, timing, timing_excluded);
        for (const auto& subject : timing_excluded)
            log_warning("{}: subject {} left out: its presentation timing failed the tolerances ({})",
                        s.timing_certificate.string(), subject, s.timing_certificate.filename().string());
    }
    auto add_sections = [&](const std::vector<std::string>& conditions) {
        if (!s.stimuli_dir.empty()) append_methods_section(s.out_dir, s.stimuli_dir, conditions);
        if (!s.timing_certificate.empty()) append_timing_section(s.out_dir, timing, timing_excluded, s.timing_certificate);
    };
    ReportSettings rs;
    rs.out_dir = s.out_dir;
    rs.source = s.input;
    rs.keywords_csv = s.keywords_csv;
    rs.confidence = s.confidence;
    rs.title = s.title;
    rs.rule_set = scores.rule_set;
    rs.dv = s.dv;

    std::vector<std::string> conditions;
    std::map<std::string, std::size_t> scored_cells;  // subject → conditions with a percent
    for (const auto& c : scores.cells) {
        if (std::find(conditions.begin(), conditions.end(), c.condition) == conditions.end())
            conditions.push_back(c.condition);
        if (c.percent) ++scored_cells[c.subject];
    }
    std::size_t complete = 0;
    for (const auto& [subject, n] : scored_cells)
        if (n == conditions.size()) ++complete;
    if (conditions.size() >= 2 && complete < 2 && !scored_cells.empty()) {
        log_warning("{}: {} subject{} with a score in every condition: no ANOVA (it needs at least 2); "
                    "writing the descriptive pilot report",
                    s.input.string(), complete, complete == 1 ? "" : "s");
        write_pilot_report(scores, rs, complete);
        add_sections(conditions);
        return std::nullopt;
    }
    const WithinData data = make_within_data(scores, s.input.string());
    AnalysisResult result = analyze(data, s.confidence);
    write_report(result, rs);
    add_sections(conditions);
    return result;
}

}  // namespace avsi::analysis
