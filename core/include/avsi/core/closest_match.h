// "Did you mean" hints: the candidate nearest a mistyped name by edit
// distance. Header-only, so the command-line front end (which links no avsi
// library) suggests the nearest command with the same rule the libraries
// use for keys, columns and values.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

namespace avsi {

// Words longer than this get no "did you mean" hint.
inline constexpr std::size_t k_max_hint_length = 64;

// Optimal-string-alignment (Damerau-Levenshtein) distance between two strings.
inline std::size_t edit_distance(const std::string& a, const std::string& b) {
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

// The closest candidate to `word` by edit distance, or "" if none is close
// enough to be a plausible typo (for "did you mean" hints) or `word` is
// longer than k_max_hint_length.
inline std::string closest_match(const std::string& word, const std::vector<std::string>& candidates) {
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

}  // namespace avsi
