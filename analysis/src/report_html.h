// Helpers the HTML reports share (report.cpp, adaptive_report.cpp and the
// sections appended to a report): base64 for images inlined as data: URIs,
// and adding a section to a written report. (Escaping is core's xml_escape,
// text.h.)
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace avsi::analysis::detail {

// Standard base64 (RFC 4648) with padding.
std::string base64(std::string_view bytes);

// Appends md to out_dir/report.md (when md is not empty and the file exists)
// and inserts html before the closing </body> of out_dir/index.html (at its
// end when it has none); index.html must exist.
void append_to_report(const std::filesystem::path& out_dir, const std::string& md, const std::string& html);

}  // namespace avsi::analysis::detail
