// The objective viseme information of a stimulus set (viseme_information.h):
// per-phone segments of the articulation measures, a cross-validated linear
// discriminant analysis per condition, and its files.
#include "avsi/stimuli/viseme_information.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/sentence_profile.h"
#include "avsi/core/text.h"

namespace avsi::stimuli {

namespace {

std::array<double, viseme_measure_count> measure_vector(const synth::ArticulationMeasures& m) {
    return {m.aperture_mid_mm,     m.mouth_width_mm, m.upper_protrusion_mm,
            m.lower_protrusion_mm, m.jaw_opening_mm, m.lip_to_incisors_mm};
}

// The classes (indices into `n_classes` sorted names) the training rows
// predict for the test rows; empty when no class has two training rows.
std::optional<std::vector<std::size_t>> lda_predict(const Eigen::MatrixXd& x, const std::vector<std::size_t>& y,
                                                    const std::vector<std::size_t>& train,
                                                    const std::vector<std::size_t>& test, std::size_t n_classes) {
    std::vector<std::size_t> count(n_classes, 0);
    for (const std::size_t i : train) ++count[y[i]];
    std::vector<std::size_t> present;              // classes in the classifier
    std::vector<std::ptrdiff_t> slot(n_classes, -1);  // class -> its row in `present`
    for (std::size_t k = 0; k < n_classes; ++k)
        if (count[k] >= 2) {
            slot[k] = std::ptrdiff_t(present.size());
            present.push_back(k);
        }
    if (present.empty()) return std::nullopt;
    const Eigen::Index d = x.cols(), p = Eigen::Index(present.size());
    Eigen::MatrixXd means = Eigen::MatrixXd::Zero(p, d);
    std::size_t n = 0;
    for (const std::size_t i : train)
        if (slot[y[i]] >= 0) {
            means.row(slot[y[i]]) += x.row(Eigen::Index(i));
            ++n;
        }
    for (Eigen::Index r = 0; r < p; ++r) means.row(r) /= double(count[present[std::size_t(r)]]);
    Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(d, d);
    for (const std::size_t i : train)
        if (slot[y[i]] >= 0) {
            const Eigen::RowVectorXd diff = x.row(Eigen::Index(i)) - means.row(slot[y[i]]);
            cov.noalias() += diff.transpose() * diff;
        }
    cov /= double(std::max<std::ptrdiff_t>(1, std::ptrdiff_t(n) - std::ptrdiff_t(p)));
    const double mean_variance = cov.trace() / double(d);
    // A set whose measures never vary gets an absolute ridge (then the priors decide).
    cov.diagonal().array() += viseme_ridge * (mean_variance > 0.0 ? mean_variance : 1.0);
    const Eigen::MatrixXd w = cov.inverse() * means.transpose();  // d × p
    Eigen::RowVectorXd bias(p);
    for (Eigen::Index r = 0; r < p; ++r)
        bias(r) = -0.5 * means.row(r).dot(w.col(r)) + std::log(double(count[present[std::size_t(r)]]) / double(n));
    std::vector<std::size_t> out;
    for (const std::size_t i : test) {
        const Eigen::RowVectorXd score = x.row(Eigen::Index(i)) * w + bias;
        Eigen::Index best = 0;
        for (Eigen::Index r = 1; r < p; ++r)
            if (score(r) > score(best)) best = r;
        out.push_back(present[std::size_t(best)]);
    }
    return out;
}

std::string shade(double share) {
    const int v = int(std::lround(255.0 - 160.0 * std::clamp(share, 0.0, 1.0)));
    return fmt::format("background:rgb({0},{0},255)", v);
}

std::string confusion_table_html(const VisemeInformation& r) {
    std::string html = "<table><tr><th>viseme \\ classified as</th>";
    for (const auto& c : r.classes) html += "<th>" + xml_escape(c) + "</th>";
    html += "<th>segments</th></tr>\n";
    for (std::size_t i = 0; i < r.classes.size(); ++i) {
        double row = 0.0;
        for (const double c : r.confusion[i]) row += c;
        html += "<tr><td>" + xml_escape(r.classes[i]) + "</td>";
        for (const double c : r.confusion[i])
            html += fmt::format("<td style=\"{}\" title=\"{:.1f} %\">{:g}</td>", shade(row > 0 ? c / row : 0.0),
                                row > 0 ? 100.0 * c / row : 0.0, c);
        html += fmt::format("<td>{:g}</td></tr>\n", row);
    }
    return html + "</table>\n";
}

}  // namespace

const std::array<const char*, viseme_measure_count>& viseme_measure_names() {
    static const std::array<const char*, viseme_measure_count> names = {
        "aperture_mid_mm", "mouth_width_mm", "upper_protrusion_mm", "lower_protrusion_mm", "jaw_opening_mm",
        "lip_to_incisors_mm"};
    return names;
}

std::vector<VisemeSegment> viseme_segments(const std::string& condition, const std::string& sentence,
                                           const PhoneSequence& phones,
                                           const std::vector<synth::ArticulationMeasures>& frames, double fps) {
    std::vector<VisemeSegment> out;
    if (frames.empty()) return out;
    const auto& inventory = PhoneInventory::builtin();
    for (const auto& phone : phones) {
        const PhoneInfo& info = inventory.info(phone.symbol, sentence);
        if (info.phone_class == PhoneClass::Silence) continue;
        VisemeSegment s{condition, sentence, phone.symbol, to_string(viseme_class(info)), {}};
        std::size_t inside = 0, nearest = 0;
        double nearest_gap = std::numeric_limits<double>::infinity();
        for (std::size_t k = 0; k < frames.size(); ++k) {
            const double t = double(k) / fps;
            if (t >= phone.start_s && t < phone.end_s) {
                const auto v = measure_vector(frames[k]);
                for (std::size_t j = 0; j < viseme_measure_count; ++j) s.measures[j] += v[j];
                ++inside;
            }
            const double gap = std::fabs(t - phone.centre_s());
            if (gap < nearest_gap) {
                nearest_gap = gap;
                nearest = k;
            }
        }
        if (inside)
            for (auto& m : s.measures) m /= double(inside);
        else
            s.measures = measure_vector(frames[nearest]);
        out.push_back(std::move(s));
    }
    return out;
}

std::optional<VisemeInformation> viseme_information(const std::string& condition,
                                                    const std::vector<VisemeSegment>& segments) {
    std::set<std::string> class_set, sentence_set;
    for (const auto& s : segments) {
        class_set.insert(s.viseme);
        sentence_set.insert(s.sentence);
    }
    if (sentence_set.size() < 2) return std::nullopt;
    VisemeInformation r;
    r.condition = condition;
    r.segments = segments.size();
    r.sentences = sentence_set.size();
    r.classes.assign(class_set.begin(), class_set.end());
    std::map<std::string, std::size_t> fold_of;
    std::size_t index = 0;
    for (const auto& id : sentence_set) fold_of[id] = index++ % viseme_folds;
    const std::size_t n = segments.size(), k = r.classes.size();
    Eigen::MatrixXd x(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(viseme_measure_count));
    std::vector<std::size_t> y(n);
    for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = 0; j < viseme_measure_count; ++j)
            x(Eigen::Index(i), Eigen::Index(j)) = segments[i].measures[j];
        y[i] = std::size_t(std::lower_bound(r.classes.begin(), r.classes.end(), segments[i].viseme) - r.classes.begin());
        r.fold.push_back(fold_of.at(segments[i].sentence));
    }
    std::vector<std::size_t> predicted(n, 0);
    for (std::size_t f = 0; f < viseme_folds; ++f) {
        std::vector<std::size_t> train, test;
        for (std::size_t i = 0; i < n; ++i) (r.fold[i] == f ? test : train).push_back(i);
        if (test.empty()) continue;
        const auto got = lda_predict(x, y, train, test, k);
        if (!got) return std::nullopt;
        for (std::size_t t = 0; t < test.size(); ++t) predicted[test[t]] = (*got)[t];
    }
    r.confusion.assign(k, std::vector<double>(k, 0.0));
    std::vector<std::size_t> per_class(k, 0);
    std::size_t correct = 0;
    for (std::size_t i = 0; i < n; ++i) {
        r.confusion[y[i]][predicted[i]] += 1.0;
        ++per_class[y[i]];
        correct += y[i] == predicted[i];
        r.predicted.push_back(r.classes[predicted[i]]);
    }
    r.accuracy = double(correct) / double(n);
    r.majority_class = double(*std::max_element(per_class.begin(), per_class.end())) / double(n);
    r.t = information_transmitted(r.confusion);
    return r;
}

void write_viseme_segments_csv(const std::filesystem::path& path, const std::vector<VisemeSegment>& segments,
                               const std::vector<VisemeInformation>& results) {
    std::string out = "condition,sentence,phone,viseme";
    for (const char* m : viseme_measure_names()) out += fmt::format(",{}", m);
    out += ",fold,predicted\n";
    std::map<std::string, std::size_t> seen;  // condition -> segments written
    for (const auto& s : segments) {
        out += fmt::format("{},{},{},{}", csv_escape(s.condition), csv_escape(s.sentence), csv_escape(s.phone),
                           csv_escape(s.viseme));
        for (const double m : s.measures) out += fmt::format(",{:.9g}", m);
        const std::size_t i = seen[s.condition]++;
        const auto r = std::find_if(results.begin(), results.end(),
                                    [&](const VisemeInformation& v) { return v.condition == s.condition; });
        if (r != results.end() && i < r->fold.size())
            out += fmt::format(",{},{}\n", r->fold[i], csv_escape(r->predicted[i]));
        else
            out += ",,\n";
    }
    write_text_file(path, out);
}

void write_viseme_information_csv(const std::filesystem::path& path, const std::vector<VisemeInformation>& results) {
    std::string out = "condition,segments,lda_accuracy,majority_class,t_bits,rti,sentences,h_x_bits\n";
    for (const auto& r : results)
        out += fmt::format("{},{},{:.4f},{:.4f},{:.4f},{:.4f},{},{:.4f}\n", csv_escape(r.condition), r.segments,
                           r.accuracy, r.majority_class, r.t.t_corrected, r.t.rti, r.sentences, r.t.h_x_corrected);
    write_text_file(path, out);
}

void write_viseme_confusions_csv(const std::filesystem::path& path, const std::vector<VisemeInformation>& results) {
    std::string out = "condition,viseme,predicted,count,row_percent\n";
    for (const auto& r : results)
        for (std::size_t i = 0; i < r.classes.size(); ++i) {
            double row = 0.0;
            for (const double c : r.confusion[i]) row += c;
            for (std::size_t j = 0; j < r.classes.size(); ++j)
                out += fmt::format("{},{},{},{:g},{:.2f}\n", csv_escape(r.condition), csv_escape(r.classes[i]),
                                   csv_escape(r.classes[j]), r.confusion[i][j],
                                   row > 0 ? 100.0 * r.confusion[i][j] / row : 0.0);
        }
    write_text_file(path, out);
}

std::string viseme_information_html(const std::string& title, const std::string& intro,
                                    const std::vector<VisemeInformation>& results) {
    std::string html = fmt::format(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0}</title>\n<style>"
        "body{{font-family:sans-serif;max-width:960px;margin:2em auto;color:#222}}"
        "table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}"
        "th{{background:#f2f2f2}}td:first-child,th:first-child{{text-align:left}}</style></head><body>\n"
        "<h1>{0}</h1>\n<p>{1}</p>\n<p><a href=\"articulation.html\">Articulation QC</a> · "
        "<a href=\"viseme_information.csv\">viseme_information.csv</a> · "
        "<a href=\"viseme_confusions.csv\">viseme_confusions.csv</a> · "
        "<a href=\"viseme_segments.csv\">viseme_segments.csv</a></p>\n",
        xml_escape(title), xml_escape(intro));
    html += "<table><tr><th>condition</th><th>segments</th><th>sentences</th><th>LDA accuracy (5-fold by "
            "sentence)</th><th>majority class</th><th>T (bits)</th><th>H(x) (bits)</th><th>RTI</th></tr>\n";
    for (const auto& r : results)
        html += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.1f} %</td><td>{:.1f} %</td><td>{:.3f}</td>"
                            "<td>{:.3f}</td><td>{:.3f}</td></tr>\n",
                            xml_escape(r.condition), r.segments, r.sentences, 100.0 * r.accuracy,
                            100.0 * r.majority_class, r.t.t_corrected, r.t.h_x_corrected, r.t.rti);
    html += "</table>\n<h2>Confusions per condition</h2>\n<p>Rows: the viseme class of the phone; columns: the class "
            "the cross-validated classifier gave its segment; numbers are segments, the shade the row "
            "percentage.</p>\n";
    for (const auto& r : results)
        html += "<h3>" + xml_escape(r.condition) + "</h3>\n" + confusion_table_html(r);
    return html + "</body></html>\n";
}

}  // namespace avsi::stimuli
