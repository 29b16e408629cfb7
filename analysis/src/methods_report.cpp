// The report's "Stimuli and audio processing" section (methods_report.h).
#include "avsi/analysis/methods_report.h"

#include <algorithm>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/text.h"
#include "report_html.h"

namespace avsi::analysis {

namespace fs = std::filesystem;
using nlohmann::json;

std::string methods_markdown_html(const std::string& markdown) {
    std::string html, paragraph;
    bool in_list = false;
    const auto close_paragraph = [&] {
        if (!paragraph.empty()) html += "<p>" + xml_escape(paragraph) + "</p>\n";
        paragraph.clear();
    };
    const auto close_list = [&] {
        if (in_list) html += "</ul>\n";
        in_list = false;
    };
    std::istringstream in(markdown);
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("# ", 0) == 0) {
            close_paragraph();
            close_list();
            html += "<h3>" + xml_escape(line.substr(2)) + "</h3>\n";
        } else if (line.rfind("- ", 0) == 0) {
            close_paragraph();
            if (!in_list) html += "<ul>\n";
            in_list = true;
            html += "<li>" + xml_escape(line.substr(2)) + "</li>\n";
        } else if (line.find_first_not_of(' ') == std::string::npos) {
            close_paragraph();
            close_list();
        } else {
            close_list();
            paragraph += (paragraph.empty() ? "" : " ") + line;
        }
    }
    close_paragraph();
    close_list();
    return html;
}

namespace {

// The set's methods text: the manifest's, else methods.md beside it.
std::string read_methods(const fs::path& stimuli_dir, const json& manifest, const fs::path& manifest_path) {
    if (manifest.contains("methods") && manifest["methods"].is_string()) return manifest["methods"].get<std::string>();
    const fs::path md = stimuli_dir / "methods.md";
    if (!fs::exists(md))
        throw InputError(manifest_path, "no \"methods\" in the manifest and no methods.md beside it: rebuild the set "
                                        "with `avsi build-stimuli` (it records the methods paragraph)");
    return read_text_file(md);
}

void check_conditions(const json& manifest, const fs::path& manifest_path, const std::vector<std::string>& conditions) {
    std::vector<std::string> built;
    if (manifest.contains("conditions") && manifest["conditions"].is_array())
        for (const auto& c : manifest["conditions"])
            if (c.contains("name") && c["name"].is_string()) built.push_back(c["name"].get<std::string>());
    std::vector<std::string> missing;
    for (const auto& c : conditions)
        if (std::find(built.begin(), built.end(), c) == built.end()) missing.push_back(c);
    if (!missing.empty())
        throw InputError(manifest_path, fmt::format("the scores' condition{} {} {} not in this stimulus set (it has {}): "
                                                    "give --stimuli the set the subjects saw",
                                                    missing.size() == 1 ? "" : "s", fmt::join(missing, ", "),
                                                    missing.size() == 1 ? "is" : "are", fmt::join(built, ", ")));
}

// The methods text with its own title dropped and its headings one level
// below the report's section heading.
std::string section_body(const std::string& methods) {
    std::string body;
    std::istringstream in(methods);
    bool first = true;
    for (std::string line; std::getline(in, line);) {
        if (first && line.rfind("# ", 0) == 0) {
            first = false;
            continue;
        }
        first = false;
        body += line + "\n";
    }
    const auto start = body.find_first_not_of('\n');
    return start == std::string::npos ? std::string() : body.substr(start);
}

}  // namespace

void append_methods_section(const fs::path& report_dir, const fs::path& stimuli_dir,
                            const std::vector<std::string>& conditions) {
    const fs::path manifest_path = stimuli_dir / "manifest.json";
    if (!fs::exists(manifest_path))
        throw InputError(manifest_path, "--stimuli: no manifest.json in this folder (give the folder `avsi "
                                        "build-stimuli --out` wrote)");
    const json manifest = read_json_file(manifest_path);
    check_conditions(manifest, manifest_path, conditions);
    const std::string body = section_body(read_methods(stimuli_dir, manifest, manifest_path));
    const std::string source = fmt::format("From the stimulus set's manifest ({}), as `avsi build-stimuli` recorded it.",
                                           manifest_path.string());
    detail::append_to_report(report_dir, "\n## Stimuli and audio processing\n\n" + source + "\n\n" + body,
                             "<h2>Stimuli and audio processing</h2>\n<p>" + xml_escape(source) + "</p>\n" +
                                 methods_markdown_html(body));
}

}  // namespace avsi::analysis
