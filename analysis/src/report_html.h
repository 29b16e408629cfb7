// Helpers the HTML reports share (report.cpp, adaptive_report.cpp): escaping
// and base64 for images inlined as data: URIs.
#pragma once

#include <string>
#include <string_view>

namespace avsi::analysis::detail {

// Escapes & < > " for HTML text and attribute values.
std::string html_escape(std::string_view s);
// Standard base64 (RFC 4648) with padding.
std::string base64(std::string_view bytes);

}  // namespace avsi::analysis::detail
