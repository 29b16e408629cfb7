// The report section "Stimuli and audio processing" (`avsi analyze --stimuli
// DIR`): the methods paragraph `avsi build-stimuli` recorded in the set's
// manifest (and wrote beside it as methods.md) — the speech, each condition's
// control model and policy, what it put on the lips, and every vocoder
// parameter a methods section must report (carrier, pulse rate and phase,
// current spread, synthesis slopes, insertion shift, n-of-m) — so the study
// report carries the stimuli's methods, not only the terminal.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace avsi::analysis {

// Reads stimuli_dir/manifest.json ("methods"; methods.md beside it for a set
// built before the manifest held it), checks that every analysed condition
// is one of the set's (an InputError naming the manifest otherwise: the
// scores and the stimuli would not belong together), and appends the
// section to report_dir's report.md (when it exists) and index.html.
void append_methods_section(const std::filesystem::path& report_dir, const std::filesystem::path& stimuli_dir,
                            const std::vector<std::string>& conditions);

// The HTML of the Markdown subset methods.md uses: "# " headings (shown as
// <h3>), "- " list items and paragraphs, every text escaped.
std::string methods_markdown_html(const std::string& markdown);

}  // namespace avsi::analysis
