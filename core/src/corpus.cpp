#include "avsi/core/corpus.h"

#include <algorithm>
#include <cctype>
#include <set>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"

namespace avsi {

namespace {

std::vector<std::string> split(const std::string& s, char sep) {
    std::vector<std::string> out;
    std::string part;
    for (char c : s) {
        if (c == sep) {
            out.push_back(trim(part));
            part.clear();
        } else {
            part += c;
        }
    }
    out.push_back(trim(part));
    return out;
}

// Lower-case words of a text, punctuation (but not apostrophes) removed.
std::vector<std::string> words_of(const std::string& text) {
    std::vector<std::string> words;
    std::string w;
    for (char ch : text) {
        const auto c = static_cast<unsigned char>(ch);
        if (std::isalnum(c) || ch == '\'' || c >= 0x80) {
            w += static_cast<char>(std::tolower(c));
        } else if (!w.empty()) {
            words.push_back(w);
            w.clear();
        }
    }
    if (!w.empty()) words.push_back(w);
    return words;
}

}  // namespace

const Sentence& Corpus::sentence(const std::string& id) const {
    for (const auto& s : sentences)
        if (s.id == id) return s;
    throw InputError(path, fmt::format("no sentence with id '{}' in the corpus", id));
}

Corpus read_corpus(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::string p = path.string();
    const std::size_t c_id = table.require_column("id");
    const std::size_t c_text = table.require_column("text");
    const std::size_t c_keywords = table.require_column("keywords");
    const auto c_list = table.column("list");
    const auto c_audio = table.column("audio");
    const auto c_labels = table.column("labels");
    const auto c_review = table.column("review");
    const std::filesystem::path base = path.parent_path();

    Corpus corpus;
    corpus.path = path;
    DiagnosticList problems;
    std::set<std::string> seen;
    for (const auto& row : table.rows) {
        Sentence s;
        s.line = row.line;
        s.id = trim(row.fields[c_id]);
        s.text = trim(row.fields[c_text]);
        if (s.id.empty()) problems.add(p, row.line, 0, "id", "expected a sentence id, got an empty field");
        else if (!seen.insert(s.id).second)
            problems.add(p, row.line, 0, "id", fmt::format("expected a unique id, got '{}' again", s.id));
        if (s.text.empty()) problems.add(p, row.line, 0, "text", "expected the sentence text, got an empty field");
        const auto text_words = words_of(s.text);
        for (const auto& spec : split(row.fields[c_keywords], ';')) {
            if (spec.empty()) continue;
            auto forms = split(spec, '|');
            forms.erase(std::remove(forms.begin(), forms.end(), std::string{}), forms.end());
            if (forms.empty()) continue;
            Keyword k;
            k.word = forms.front();
            k.alternates.assign(forms.begin() + 1, forms.end());
            for (const auto& kw : words_of(k.word))
                if (std::find(text_words.begin(), text_words.end(), kw) == text_words.end())
                    problems.add(p, row.line, 0, "keywords",
                                 fmt::format("expected each keyword to be a word of the sentence, got "
                                             "'{}' which is not in \"{}\"", k.word, s.text));
            s.keywords.push_back(std::move(k));
        }
        if (s.keywords.empty())
            problems.add(p, row.line, 0, "keywords",
                         "expected at least one keyword ('word|alternate;word;…'), got none");
        if (c_list) s.list = trim(row.fields[*c_list]);
        if (c_audio && !trim(row.fields[*c_audio]).empty()) s.audio = base / trim(row.fields[*c_audio]);
        if (c_labels && !trim(row.fields[*c_labels]).empty()) s.labels = base / trim(row.fields[*c_labels]);
        if (c_review) s.review = trim(row.fields[*c_review]);
        if (s.audio.empty() != s.labels.empty())
            problems.add(p, row.line, 0, s.audio.empty() ? "audio" : "labels",
                         "expected both a recording and its phone labels, or neither");
        corpus.sentences.push_back(std::move(s));
    }
    if (table.rows.empty()) problems.add(p, 2, 0, "", "expected at least one sentence, got none");
    problems.throw_if_any();
    return corpus;
}

void write_corpus(const std::filesystem::path& path, const Corpus& corpus) {
    bool any_list = false, any_media = false, any_review = false;
    for (const auto& s : corpus.sentences) {
        any_list |= !s.list.empty();
        any_media |= !s.audio.empty();
        any_review |= !s.review.empty();
    }
    std::vector<std::string> header{"id", "text", "keywords"};
    if (any_list) header.push_back("list");
    if (any_media) {
        header.push_back("audio");
        header.push_back("labels");
    }
    if (any_review) header.push_back("review");
    std::string out = csv_line(header);
    const auto base = path.parent_path();
    for (const auto& s : corpus.sentences) {
        std::string keywords;
        for (const auto& k : s.keywords) {
            if (!keywords.empty()) keywords += ';';
            keywords += k.word;
            for (const auto& a : k.alternates) keywords += '|' + a;
        }
        std::vector<std::string> fields{s.id, s.text, keywords};
        if (any_list) fields.push_back(s.list);
        if (any_media) {
            fields.push_back(s.audio.empty() ? "" : s.audio.lexically_relative(base).string());
            fields.push_back(s.labels.empty() ? "" : s.labels.lexically_relative(base).string());
        }
        if (any_review) fields.push_back(s.review);
        out += csv_line(fields);
    }
    write_text_file(path, out);
}

}  // namespace avsi
