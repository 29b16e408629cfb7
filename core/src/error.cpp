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

std::size_t edit_distance(const std::string& a, const std::string& b) {
    const std::size_t n = a.size(), m = b.size();
    std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
    for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
    for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
    for (std::size_t i = 1; i <= n; ++i) {
        for (std::size_t j = 1; j <= m; ++j) {
            const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    }
    return d[n][m];
}

std::string closest_match(const std::string& word, const std::vector<std::string>& candidates) {
    // Only short tokens can be typos of a name; the distance is quadratic in
    // the length, so a megabyte-long label must not reach it.
    if (word.size() > k_max_hint_length) return {};
    std::string best;
    std::size_t best_distance = std::max<std::size_t>(2, word.size() / 3) + 1;
    for (const auto& c : candidates) {
        const std::size_t dist = edit_distance(word, c);
        if (dist < best_distance) {
            best_distance = dist;
            best = c;
        }
    }
    return best;
}

namespace detail {
void assertion_failed(const char* expression, const char* file, int line) {
    std::fprintf(stderr, "%s:%d: internal error: assertion failed: %s\n", file, line, expression);
    std::abort();
}
}  // namespace detail

}  // namespace avsi
