// Text helpers (text.h).
#include "avsi/core/text.h"

#include <cctype>

namespace avsi {

std::string_view trim_view(std::string_view s) {
    std::size_t a = 0, b = s.size();
    while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
    while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
    return s.substr(a, b - a);
}

std::string trim(std::string_view s) { return std::string(trim_view(s)); }

std::string ascii_lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

std::string xml_escape(std::string_view s) {
    std::string out;
    out.reserve(s.size());
    for (char c : s) {
        switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            default: out += c;
        }
    }
    return out;
}

std::vector<std::string> text_words(std::string_view text) {
    std::vector<std::string> words;
    std::string w;
    auto flush = [&] {
        while (!w.empty() && w.back() == '\'') w.pop_back();
        while (!w.empty() && w.front() == '\'') w.erase(w.begin());
        if (!w.empty()) words.push_back(w);
        w.clear();
    };
    for (char ch : text) {
        const auto c = static_cast<unsigned char>(ch);
        if (std::isalnum(c) || ch == '\'' || c >= 0x80) w += ch;
        else flush();
    }
    flush();
    return words;
}

}  // namespace avsi
