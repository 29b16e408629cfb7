// "What each model conveys": confusion heat maps, RTI per feature and the
// phoneme-level mixed model script (phoneme_report.h).
#include "avsi/analysis/phoneme_report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include <cairo.h>
#include <fmt/format.h>

#include "avsi/analysis/phoneme_information.h"
#include "avsi/analysis/phoneme_scoring.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"
#include "plot_axes.h"
#include "report_html.h"

namespace avsi::analysis {
namespace {

namespace fs = std::filesystem;

// A name safe in a file name ("ANN 1" -> "ann-1").
std::string file_stem(const std::string& s) {
    std::string out;
    for (char c : s)
        out += std::isalnum(static_cast<unsigned char>(c)) ? char(std::tolower(static_cast<unsigned char>(c))) : '-';
    return out;
}

double row_total(const std::vector<double>& r) {
    double t = 0.0;
    for (double c : r) t += c;
    return t;
}

void write_figure_png(cairo_surface_t* surface, const fs::path& path) {
    AtomicFile file(path);
    if (cairo_surface_write_to_png(surface, file.temp_path().c_str()) != CAIRO_STATUS_SUCCESS)
        throw InputError(path, "cannot write the figure");
    file.commit();
}

void draw_text(cairo_t* cr, double x, double y, const std::string& text, double size, bool centre = false,
               bool rotate = false) {
    cairo_set_font_size(cr, size);
    cairo_text_extents_t e;
    cairo_text_extents(cr, text.c_str(), &e);
    cairo_save(cr);
    cairo_move_to(cr, x, y);
    if (rotate) cairo_rotate(cr, -M_PI / 2);
    if (centre) cairo_rel_move_to(cr, -e.width / 2, 0);
    cairo_show_text(cr, text.c_str());
    cairo_restore(cr);
}

// The heat map of one matrix: cell shade = row percentage (white 0, dark blue
// 100), the count written in each non-empty cell, targets down, responses across.
void write_heatmap(const ConfusionMatrix& m, const std::string& title, const fs::path& path) {
    const double cell_px = m.columns.size() > 12 ? 22 : 52, left = 110, top = 70, bottom = 50;
    const int width = int(left + cell_px * double(m.columns.size()) + 30);
    const int height = int(top + cell_px * double(m.rows.size()) + bottom);
    cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
    cairo_t* cr = cairo_create(surface);
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_source_rgb(cr, 0, 0, 0);
    draw_text(cr, 10, 22, title, 15);
    for (std::size_t i = 0; i < m.rows.size(); ++i) {
        const double total = row_total(m.counts[i]);
        const double y = top + cell_px * double(i);
        cairo_set_source_rgb(cr, 0, 0, 0);
        draw_text(cr, 8, y + cell_px * 0.65, m.rows[i], cell_px > 30 ? 11 : 10);
        for (std::size_t j = 0; j < m.columns.size(); ++j) {
            const double share = total > 0 ? m.counts[i][j] / total : 0.0;
            const double x = left + cell_px * double(j);
            cairo_set_source_rgb(cr, 1.0 - 0.85 * share, 1.0 - 0.7 * share, 1.0 - 0.3 * share);
            cairo_rectangle(cr, x, y, cell_px - 1, cell_px - 1);
            cairo_fill(cr);
            if (m.counts[i][j] > 0) {
                share > 0.5 ? cairo_set_source_rgb(cr, 1, 1, 1) : cairo_set_source_rgb(cr, 0, 0, 0);
                draw_text(cr, x + cell_px / 2, y + cell_px * 0.62, fmt::format("{:g}", m.counts[i][j]),
                          cell_px > 30 ? 11 : 8, true);
            }
        }
    }
    cairo_set_source_rgb(cr, 0, 0, 0);
    for (std::size_t j = 0; j < m.columns.size(); ++j)
        draw_text(cr, left + cell_px * (double(j) + 0.65), top - 6, m.columns[j], cell_px > 30 ? 10 : 9, false, true);
    draw_text(cr, 10, height - 18,
              "rows: target; columns: response (- deleted); shade: row percentage; numbers: counts", 11);
    cairo_destroy(cr);
    cairo_surface_flush(surface);
    write_figure_png(surface, path);
    cairo_surface_destroy(surface);
}

// RTI by feature grouping (groups of bars) and condition, with the CIs.
void write_rti_plot(const InformationResult& info, const std::vector<std::string>& conditions, const fs::path& path) {
    const int width = 900, height = 480;
    const detail::PlotArea area{70, 50, 800, 330};
    cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
    cairo_t* cr = cairo_create(surface);
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    const auto y_of = [&](double v) { return area.top + area.height * (1.0 - std::clamp(v, 0.0, 1.0)); };
    detail::draw_y_grid(cr, area, 0.0, 1.0, 0.1, y_of, [](double v) { return fmt::format("{:.1f}", v); });
    detail::draw_axes(cr, area);
    const auto& groupings = feature_grouping_names();
    const double group_w = area.width / double(groupings.size());
    const double bar_w = group_w * 0.8 / double(std::max<std::size_t>(1, conditions.size()));
    for (std::size_t g = 0; g < groupings.size(); ++g) {
        for (std::size_t c = 0; c < conditions.size(); ++c) {
            const auto it = std::find_if(info.rows.begin(), info.rows.end(), [&](const InformationRow& r) {
                return r.feature == groupings[g] && r.condition == conditions[c];
            });
            if (it == info.rows.end()) continue;
            const double x = area.left + group_w * double(g) + group_w * 0.1 + bar_w * double(c);
            const double shade = double(c) / double(std::max<std::size_t>(1, conditions.size()));
            cairo_set_source_rgb(cr, 0.2 + 0.6 * shade, 0.4 + 0.3 * shade, 0.8 - 0.5 * shade);
            cairo_rectangle(cr, x, y_of(it->t.rti), bar_w - 2, y_of(0.0) - y_of(it->t.rti));
            cairo_fill(cr);
            if (std::isfinite(it->ci_low) && std::isfinite(it->ci_high)) {
                cairo_set_source_rgb(cr, 0, 0, 0);
                cairo_set_line_width(cr, 1.2);
                cairo_move_to(cr, x + bar_w / 2 - 1, y_of(it->ci_low));
                cairo_line_to(cr, x + bar_w / 2 - 1, y_of(it->ci_high));
                cairo_stroke(cr);
            }
        }
        cairo_set_source_rgb(cr, 0, 0, 0);
        draw_text(cr, area.left + group_w * (double(g) + 0.5), area.top + area.height + 18, groupings[g], 12, true);
    }
    for (std::size_t c = 0; c < conditions.size(); ++c) {
        const double shade = double(c) / double(std::max<std::size_t>(1, conditions.size()));
        const double x = area.left + 10 + 130 * double(c % 6), y = area.top + area.height + 40 + 18 * double(c / 6);
        cairo_set_source_rgb(cr, 0.2 + 0.6 * shade, 0.4 + 0.3 * shade, 0.8 - 0.5 * shade);
        cairo_rectangle(cr, x, y - 10, 12, 12);
        cairo_fill(cr);
        cairo_set_source_rgb(cr, 0, 0, 0);
        draw_text(cr, x + 16, y, conditions[c], 11);
    }
    detail::draw_titles(cr, area, "Relative information transmitted per feature", "RTI (Miller-Madow)",
                        "error bars: 95 % subject-bootstrap CI", height - 12);
    cairo_destroy(cr);
    cairo_surface_flush(surface);
    write_figure_png(surface, path);
    cairo_surface_destroy(surface);
}

// phonemes_glmer.csv: one row per target phone with its feature classes.
void write_glmer_data(const std::vector<PhonemeRow>& rows, const fs::path& path) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::string out = "subject,condition,sentence,target,correct";
    for (const auto& g : feature_grouping_names()) out += "," + g;
    out += "\n";
    for (const auto& r : rows) {
        if (r.outcome == PhoneOutcome::Inserted) continue;
        std::vector<std::string> f = {r.subject, r.condition, r.sentence, r.target,
                                      r.outcome == PhoneOutcome::Correct ? "1" : "0"};
        for (const auto& g : feature_grouping_names()) {
            const std::string c = feature_category(g, inventory.info(r.target), false);
            f.push_back(c.empty() ? "NA" : c);
        }
        out += csv_line(f);
    }
    write_text_file(path, out);
}

std::string r_levels(const std::vector<std::string>& conditions) {
    std::string out;
    for (const auto& c : conditions) {
        std::string q = "\"";
        for (char ch : c) q += ch == '"' || ch == '\\' ? std::string("\\") + ch : std::string(1, ch);
        out += (out.empty() ? "" : ", ") + q + "\"";
    }
    return out;
}

std::string glmer_phonemes_script(const std::vector<std::string>& conditions) {
    return fmt::format(R"(# Phoneme-level mixed-effects logistic model (written by avsi analyze --phonemes).
# Per target phone: correct (1) or not (substituted or deleted), by condition,
# the phone's class under one feature grouping, and their interaction, with
# random intercepts for subject, sentence and target phone:
#   correct ~ condition * class + (1 | subject) + (1 | sentence) + (1 | target)
# Usage: Rscript glmer_phonemes.R [phonemes_glmer.csv] [grouping]
# grouping: voicing, manner, place (consonant targets), rounding, viseme (all);
# default voicing. Needs lme4 (install.packages("lme4")).
args <- commandArgs(trailingOnly = TRUE)
path <- if (length(args) >= 1) args[1] else "phonemes_glmer.csv"
grouping <- if (length(args) >= 2) args[2] else "voicing"
suppressPackageStartupMessages(library(lme4))
d <- read.csv(path, stringsAsFactors = FALSE)
if (!(grouping %in% names(d))) stop(paste("no column", grouping, "in", path))
d$class <- d[[grouping]]
d <- d[!is.na(d$class), ]
d$condition <- factor(d$condition, levels = c({}))
d$class <- factor(d$class)
m <- glmer(correct ~ condition * class + (1 | subject) + (1 | sentence) + (1 | target), data = d,
           family = binomial, control = glmerControl(optimizer = "bobyqa"))
print(summary(m))
if (requireNamespace("car", quietly = TRUE)) print(car::Anova(m, type = 3))
)",
                       r_levels(conditions));
}

std::string fixed3_or_na(double x) { return std::isfinite(x) ? fmt::format("{:.3f}", x) : "NA"; }

std::string information_table_md(const InformationResult& info) {
    std::string md =
        "| condition | feature | phones | H(x) bits | T bits (Miller-Madow) | RTI | 95 % CI |\n"
        "| --- | --- | ---: | ---: | ---: | ---: | --- |\n";
    for (const auto& r : info.rows)
        md += fmt::format("| {} | {} | {:g} | {:.3f} | {:.3f} | {:.3f} | {} – {} |\n", r.condition, r.feature, r.t.n,
                          r.t.h_x_corrected, r.t.t_corrected, r.t.rti, fixed3_or_na(r.ci_low), fixed3_or_na(r.ci_high));
    return md;
}

std::string comparisons_table_md(const InformationResult& info) {
    std::string md =
        "| feature | pair | RTI difference | 95 % CI | p (bootstrap) | p Holm |\n"
        "| --- | --- | ---: | --- | ---: | ---: |\n";
    for (const auto& c : info.comparisons)
        md += fmt::format("| {} | {} − {} | {:.3f} | {} – {} | {} | {} |\n", c.feature, c.condition_a, c.condition_b,
                          c.difference, fixed3_or_na(c.ci_low), fixed3_or_na(c.ci_high), fixed3_or_na(c.p),
                          fixed3_or_na(c.p_holm));
    return md;
}

// A Markdown table as HTML (the section's tables are simple pipes).
std::string md_table_to_html(const std::string& md) {
    std::string h = "<table>\n";
    std::size_t line_no = 0, start = 0;
    while (start < md.size()) {
        const std::size_t end = md.find('\n', start);
        const std::string line = md.substr(start, end - start);
        start = end == std::string::npos ? md.size() : end + 1;
        if (line_no++ == 1) continue;  // the alignment row
        std::vector<std::string> cells;
        std::size_t from = 1;
        while (from < line.size()) {
            const std::size_t bar = line.find(" |", from);
            if (bar == std::string::npos) break;
            std::string c = line.substr(from, bar - from);
            while (!c.empty() && c.front() == ' ') c.erase(c.begin());
            cells.push_back(c);
            from = bar + 2;
        }
        const char* tag = line_no == 1 ? "th" : "td";
        h += "<tr>";
        for (const auto& c : cells) h += fmt::format("<{0}>{1}</{0}>", tag, xml_escape(c));
        h += "</tr>\n";
    }
    return h + "</table>\n";
}

struct PhonemeFigure {
    std::string file, caption;
};

std::string section_intro(const InformationResult& info, const std::vector<PhonemeRow>& rows) {
    std::size_t targets = 0, correct = 0;
    for (const auto& r : rows) {
        targets += r.outcome == PhoneOutcome::Inserted ? 0 : 1;
        correct += r.outcome == PhoneOutcome::Correct ? 1 : 0;
    }
    return fmt::format(
        "Every typed answer aligned phone by phone with its sentence (phonemes.csv: {} target phones, {:.1f} % "
        "correct). Information transmitted per feature after Miller & Nicely (1955), T(x;y) and RTI = T / H(x) "
        "with the Miller-Madow bias correction of each entropy; deletions are a response category of their own. "
        "95 % CIs: subject-level bootstrap ({} replicates, seed {}); pairs of conditions: paired bootstrap of the "
        "RTI difference, Holm-adjusted within a feature.",
        targets, targets ? 100.0 * double(correct) / double(targets) : 0.0, info.bootstrap, info.seed);
}

// The rows with the listed conditions first, in that order (stable otherwise).
std::vector<PhonemeRow> in_condition_order(std::vector<PhonemeRow> rows, const std::vector<std::string>& order) {
    const auto rank = [&](const std::string& c) {
        return static_cast<std::size_t>(std::find(order.begin(), order.end(), c) - order.begin());
    };
    std::stable_sort(rows.begin(), rows.end(),
                     [&](const PhonemeRow& a, const PhonemeRow& b) { return rank(a.condition) < rank(b.condition); });
    return rows;
}

// The objective table: per condition of viseme_information.csv, the face's
// LDA accuracy and RTI beside the listeners' viseme RTI and its CI.
std::string objective_table_md(const fs::path& path, const InformationResult& info) {
    const CsvTable t = read_csv(path);
    const std::size_t condition = t.require_column("condition"), accuracy = t.require_column("lda_accuracy"),
                      chance = t.require_column("majority_class"), rti = t.require_column("rti");
    std::vector<Diagnostic> problems;
    std::string md = "| condition | face: LDA accuracy | majority class | face: viseme RTI | listeners: viseme RTI "
                     "(95 % CI) |\n| --- | ---: | ---: | ---: | --- |\n";
    for (const auto& row : t.rows) {
        if (row.fields.size() < t.header.size()) {
            problems.push_back({path.string(), row.line, 1, "row", "expected every column of the header"});
            continue;
        }
        const auto a = parse_double(row.fields[accuracy]), c = parse_double(row.fields[chance]),
                   r = parse_double(row.fields[rti]);
        if (!a || !c || !r) {
            problems.push_back({path.string(), row.line, 1, !a ? "lda_accuracy" : !c ? "majority_class" : "rti",
                                "expected a number"});
            continue;
        }
        std::string listeners = "not tested";
        for (const auto& i : info.rows)
            if (i.feature == "viseme" && i.condition == row.fields[condition])
                listeners = fmt::format("{:.3f} ({} – {})", i.t.rti, fixed3_or_na(i.ci_low), fixed3_or_na(i.ci_high));
        md += fmt::format("| {} | {:.1f} % | {:.1f} % | {:.3f} | {} |\n", row.fields[condition], 100.0 * *a,
                          100.0 * *c, *r, listeners);
    }
    if (!problems.empty()) throw InputError(problems);
    return md;
}

}  // namespace

void append_phoneme_section(const PhonemeReportSettings& s) {
    const std::vector<PhonemeRow> rows = in_condition_order(read_phonemes_csv(s.phonemes_csv), s.conditions);
    std::vector<std::string> conditions;
    for (const auto& r : rows)
        if (std::find(conditions.begin(), conditions.end(), r.condition) == conditions.end())
            conditions.push_back(r.condition);
    std::vector<ConfusionMatrix> matrices;
    std::vector<PhonemeFigure> figures;
    for (const auto& c : conditions)
        for (auto& m : confusion_matrices(c, rows)) {
            if (m.kind != "vowels") {
                const std::string file = fmt::format("confusion_{}_{}.png", file_stem(c), m.kind);
                write_heatmap(m, fmt::format("{}: {} confusions", c, m.kind), s.out_dir / file);
                figures.push_back({file, fmt::format("{}: {}", c, m.kind)});
            }
            matrices.push_back(std::move(m));
        }
    write_confusions_csv(s.out_dir / "confusions.csv", matrices);
    const InformationResult info = information_by_condition(rows, {s.bootstrap, s.seed});
    write_information_csv(s.out_dir / "information.csv", info);
    write_information_comparisons_csv(s.out_dir / "information_comparisons.csv", info);
    write_rti_plot(info, conditions, s.out_dir / "rti.png");
    write_glmer_data(rows, s.out_dir / "phonemes_glmer.csv");
    write_text_file(s.out_dir / "glmer_phonemes.R", glmer_phonemes_script(conditions));

    const std::string banner = s.banner.empty() ? "" : "**" + s.banner + "**\n\n";
    const std::string intro = section_intro(info, rows);
    std::string md = "\n## What each model conveys\n\n" + banner + intro + "\n\n![RTI per feature](rti.png)\n\n" +
                     information_table_md(info) + "\n" + comparisons_table_md(info) + "\n";
    std::string html = "<h2>What each model conveys</h2>\n" +
                       (s.banner.empty() ? "" : "<p><strong>" + xml_escape(s.banner) + "</strong></p>\n") + "<p>" +
                       xml_escape(intro) +
                       "</p>\n<img alt=\"RTI per feature and condition\" src=\"data:image/png;base64," +
                       detail::base64(read_text_file(s.out_dir / "rti.png")) + "\"/>\n" +
                       md_table_to_html(information_table_md(info)) + md_table_to_html(comparisons_table_md(info));
    for (const auto& f : figures) {
        md += fmt::format("![{}]({})\n\n", f.caption, f.file);
        html += fmt::format("<img alt=\"{}\" src=\"data:image/png;base64,{}\"/>\n", xml_escape(f.caption),
                            detail::base64(read_text_file(s.out_dir / f.file)));
    }
    const std::string files =
        "Files: confusions.csv (counts and row percentages: consonants, vowels, viseme classes), "
        "information.csv, information_comparisons.csv, phonemes_glmer.csv and glmer_phonemes.R "
        "(phoneme-level lme4 model: Rscript glmer_phonemes.R phonemes_glmer.csv voicing).";
    md += files + "\n";
    html += "<p class=\"note\">" + xml_escape(files) + "</p>\n";
    if (!s.objective_csv.empty()) {
        const std::string table = objective_table_md(s.objective_csv, info);
        const std::string intro = fmt::format(
            "What each model's face carries about the viseme class before any listener ({}: build-stimuli's "
            "cross-validated LDA on the rendered articulation measures of each phone), beside what the listeners got.",
            s.objective_csv.filename().string());
        md += "\n### Objective viseme information\n\n" + intro + "\n\n" + table;
        html += "<h3>Objective viseme information</h3>\n<p>" + xml_escape(intro) + "</p>\n" + md_table_to_html(table);
    }
    detail::append_to_report(s.out_dir, md, html);
    log_info("phoneme section: {} conditions, {} figures, RTI of {} features", conditions.size(), figures.size() + 1,
             feature_grouping_names().size());
}

}  // namespace avsi::analysis
