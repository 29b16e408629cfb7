#include "avsi/core/error.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <numeric>

namespace avsi {

std::string Diagnostic::format() const {
    std::string out = path.empty() ? std::string("<input>") : path;
    if (line > 0) {
        out += ':' + std::to_string(line);
        if (column > 0) out += ':' + std::to_string(column);
    }
    out += ": error: ";
    if (!field.empty()) out += field + ": ";
    out += message;
    return out;
}

namespace {
std::string join_formatted(const std::vector<Diagnostic>& items) {
    std::string out;
    for (const auto& d : items) {
        if (!out.empty()) out += '\n';
        out += d.format();
    }
    return out;
}
}  // namespace

InputError::InputError(Diagnostic diagnostic)
    : InputError(std::vector<Diagnostic>{std::move(diagnostic)}) {}

InputError::InputError(std::vector<Diagnostic> diagnostics)
    : std::runtime_error(join_formatted(diagnostics)), m_diagnostics(std::move(diagnostics)) {
    AVSI_ASSERT(!m_diagnostics.empty());
}

InputError::InputError(std::string path, int line, int column, std::string field,
                       std::string message)
    : InputError(Diagnostic{std::move(path), line, column, std::move(field), std::move(message)}) {}

InputError::InputError(const std::filesystem::path& path, std::string message)
    : InputError(Diagnostic{path.string(), 0, 0, "", std::move(message)}) {}

void DiagnosticList::add(std::string path, int line, int column, std::string field,
                         std::string message) {
    m_items.push_back({std::move(path), line, column, std::move(field), std::move(message)});
}

void DiagnosticList::throw_if_any() const {
    if (!m_items.empty()) throw InputError(m_items);
}

std::string excerpt(std::string_view text, std::size_t max_bytes) {
    std::size_t cut = std::min(max_bytes, text.size());
    while (cut > 0 && cut < text.size() && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
    std::string out;
    for (const char c : text.substr(0, cut)) {
        const auto u = static_cast<unsigned char>(c);
        if (u < 0x20 || u == 0x7F) {  // control characters (NUL, line breaks) shown escaped
            static const char* hex = "0123456789abcdef";
            out += "\\x";
            out += hex[u >> 4];
            out += hex[u & 15];
        } else {
            out += c;
        }
    }
    if (cut < text.size()) out += "… (" + std::to_string(text.size()) + " bytes)";
    return out;
}

namespace detail {
void assertion_failed(const char* expression, const char* file, int line) {
    std::fprintf(stderr, "%s:%d: internal error: assertion failed: %s\n", file, line, expression);
    std::abort();
}
}  // namespace detail

}  // namespace avsi
