// Helpers the HTML reports share (report.cpp, adaptive_report.cpp): base64
// for images inlined as data: URIs. (Escaping is core's xml_escape, text.h.)
#pragma once

#include <string>
#include <string_view>

namespace avsi::analysis::detail {

// Standard base64 (RFC 4648) with padding.
std::string base64(std::string_view bytes);

}  // namespace avsi::analysis::detail
