// Corpus tools: word table, sentence profiles, seeded list balancing and
// keyword proposals (see corpus_tools.h). The morphological rules are
// WordNet's morphy detachment rules (WordNet 3.0, morph.c / morphy(7WN)).
#include "avsi/core/corpus_tools.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <numeric>
#include <regex>
#include <sstream>

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"

namespace avsi {

namespace {

// Words of a text as written (letters, digits, apostrophes, non-ASCII bytes);
// a trailing possessive "'s" stays part of the word.
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

bool ends_with(std::string_view s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

struct Detachment {
    char pos;
    const char* suffix;
    const char* ending;
};
// morphy's detachment rules.
constexpr Detachment detachments[] = {
    {'n', "s", ""},    {'n', "ses", "s"}, {'n', "xes", "x"}, {'n', "zes", "z"}, {'n', "ches", "ch"},
    {'n', "shes", "sh"}, {'n', "men", "man"}, {'n', "ies", "y"},
    {'v', "s", ""},    {'v', "ies", "y"}, {'v', "es", "e"},  {'v', "es", ""},   {'v', "ed", "e"},
    {'v', "ed", ""},   {'v', "ing", "e"}, {'v', "ing", ""},
    {'a', "er", ""},   {'a', "est", ""},  {'a', "er", "e"},  {'a', "est", "e"},
};

double mean(const std::vector<double>& v) {
    if (v.empty()) return 0.0;
    return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

double sd(const std::vector<double>& v) {
    if (v.size() < 2) return 0.0;
    const double m = mean(v);
    double s = 0.0;
    for (double x : v) s += (x - m) * (x - m);
    return std::sqrt(s / static_cast<double>(v.size() - 1));
}

const PhoneInfo* phone_info(const Phone& p) {
    const auto& inv = PhoneInventory::builtin();
    if (p.symbol == "sil" || !inv.contains(p.symbol)) return nullptr;
    return &inv.info(p.symbol);
}

}  // namespace

// ------------------------------------------------------------------ WordTable

const WordTable& WordTable::builtin() {
    static const WordTable table = load(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "word-frequency.tsv",
                                        std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "function-words.txt",
                                        std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "word-zipf.tsv");
    return table;
}

WordTable WordTable::load(const std::filesystem::path& frequency_tsv, const std::filesystem::path& function_words,
                          const std::filesystem::path& zipf_tsv) {
    WordTable t;
    CsvOptions options;
    options.delimiter = '\t';
    const CsvTable table = read_csv(frequency_tsv, options);
    const std::size_t c_word = table.require_column("word");
    const std::size_t c_lemma = table.require_column("lemma");
    const std::size_t c_count = table.require_column("count");
    const std::size_t c_pos = table.require_column("pos");
    DiagnosticList problems;
    const std::string p = frequency_tsv.string();
    for (const auto& row : table.rows) {
        const auto count = parse_int(row.fields[c_count]);
        if (!count || *count < 0) {
            problems.add(p, row.line, 0, "count",
                         fmt::format("expected a count ≥ 0, got \"{}\"", row.fields[c_count]));
            continue;
        }
        const std::string pos = row.fields[c_pos];
        if (pos.find_first_not_of("nvar") != std::string::npos)
            problems.add(p, row.line, 0, "pos", fmt::format("expected letters of \"nvar\", got \"{}\"", pos));
        WordFrequency f{ascii_lower(row.fields[c_lemma]), *count, pos};
        const std::string word = ascii_lower(row.fields[c_word]);
        if (word == f.lemma) t.m_lemma_pos[f.lemma] = pos;
        t.m_rows.emplace(word, std::move(f));
    }
    problems.throw_if_any();
    std::istringstream in(read_text_file(function_words));
    std::string line;
    while (std::getline(in, line)) {
        line = trim(line);
        if (line.empty() || line[0] == '#') continue;
        t.m_function_words.insert(ascii_lower(line));
    }
    if (!zipf_tsv.empty()) {
        const CsvTable z = read_csv(zipf_tsv, options);
        const std::size_t c_zword = z.require_column("word");
        const std::size_t c_zipf = z.require_column("zipf");
        for (const auto& row : z.rows) {
            const auto v = parse_double(row.fields[c_zipf]);
            if (!v || !std::isfinite(*v)) {
                problems.add(zipf_tsv.string(), row.line, 0, "zipf",
                             fmt::format("expected a number, got \"{}\"", row.fields[c_zipf]));
                continue;
            }
            t.m_zipf[ascii_lower(row.fields[c_zword])] = *v;
        }
        problems.throw_if_any();
    }
    return t;
}

std::optional<double> WordTable::zipf(std::string_view word_in) const {
    std::string word = ascii_lower(word_in);
    auto it = m_zipf.find(word);
    if (it == m_zipf.end() && ends_with(word, "'s")) it = m_zipf.find(word.substr(0, word.size() - 2));
    if (it == m_zipf.end()) return std::nullopt;
    return it->second;
}

std::vector<WordFrequency> WordTable::lookup(std::string_view word_in) const {
    std::string word = ascii_lower(word_in);
    if (ends_with(word, "'s")) word.resize(word.size() - 2);
    std::vector<WordFrequency> out;
    auto add = [&](const WordFrequency& f) {
        for (const auto& o : out)
            if (o.lemma == f.lemma) return;
        out.push_back(f);
    };
    const auto [first, last] = m_rows.equal_range(word);
    for (auto it = first; it != last; ++it) add(it->second);
    for (const auto& d : detachments) {
        if (!ends_with(word, d.suffix) || word.size() <= std::char_traits<char>::length(d.suffix) + 1) continue;
        const std::string lemma = word.substr(0, word.size() - std::char_traits<char>::length(d.suffix)) + d.ending;
        const auto it = m_lemma_pos.find(lemma);
        if (it == m_lemma_pos.end() || it->second.find(d.pos) == std::string::npos) continue;
        const auto [f, l] = m_rows.equal_range(lemma);
        for (auto r = f; r != l; ++r)
            if (r->second.lemma == lemma) add(r->second);
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const WordFrequency& a, const WordFrequency& b) { return a.count > b.count; });
    return out;
}

double WordTable::log_frequency(std::string_view word) const {
    const auto found = lookup(word);
    return found.empty() ? 0.0 : std::log10(1.0 + static_cast<double>(found.front().count));
}

bool WordTable::is_function_word(std::string_view word) const {
    return m_function_words.count(ascii_lower(word)) > 0;
}

// ------------------------------------------------------------------ visemes

const char* to_string(VisemeClass c) {
    switch (c) {
        case VisemeClass::Bilabial: return "bilabial";
        case VisemeClass::Labiodental: return "labiodental";
        case VisemeClass::Dental: return "dental";
        case VisemeClass::Rounded: return "rounded";
        case VisemeClass::OpenVowel: return "open vowel";
        case VisemeClass::SpreadVowel: return "spread vowel";
        case VisemeClass::Lingual: return "lingual";
        case VisemeClass::Count: break;
    }
    return "?";
}

VisemeClass viseme_class(const PhoneInfo& phone) {
    const auto f = [&](Feature k) { return phone.features[static_cast<std::size_t>(k)]; };
    const bool vowel = phone.phone_class == PhoneClass::Vowel;
    const bool rounded = f(Feature::Rounded) >= 0.5f || f(Feature::Protruded) >= 0.5f;
    if (!vowel && f(Feature::Labiodental) > 0.5f) return VisemeClass::Labiodental;
    if (!vowel && f(Feature::Dental) > 0.5f) return VisemeClass::Dental;
    if (!vowel && f(Feature::Bilabial) > 0.5f && !rounded) return VisemeClass::Bilabial;
    if (rounded) return VisemeClass::Rounded;
    if (vowel) return f(Feature::Open) >= 1.0f ? VisemeClass::OpenVowel : VisemeClass::SpreadVowel;
    return VisemeClass::Lingual;
}

// ------------------------------------------------------------------ profiles

double SentenceProfile::mean_log_frequency() const { return mean(keyword_log_frequency); }

int SentenceProfile::keyword_phones() const { return std::accumulate(keyword_visemes.begin(), keyword_visemes.end(), 0); }

int count_syllables(const std::string& text, const std::string& voice) {
    TtsSettings tts;
    tts.voice = voice;
    const TtsResult r = synthesize_speech(text, tts);
    const auto& inv = PhoneInventory::builtin();
    return static_cast<int>(std::count_if(r.phones.begin(), r.phones.end(),
                                          [&](const Phone& p) { return inv.is_vowel(p.symbol); }));
}

SentenceProfile profile_sentence(const Sentence& sentence, const WordTable& words, const ProfileSettings& settings) {
    SentenceProfile p;
    p.id = sentence.id;
    p.syllables = count_syllables(sentence.text, settings.voice);
    TtsSettings tts;
    tts.voice = settings.voice;
    for (const auto& k : sentence.keywords) {
        // A multi-word keyword: the mean over its words.
        const auto parts = text_words(k.word);
        std::vector<double> f;
        for (const auto& w : parts) f.push_back(words.log_frequency(w));
        p.keyword_log_frequency.push_back(mean(f));
        for (const Phone& ph : synthesize_speech(k.word, tts).phones)
            if (const PhoneInfo* info = phone_info(ph))
                ++p.keyword_visemes[static_cast<std::size_t>(viseme_class(*info))];
    }
    return p;
}

// ------------------------------------------------------------------ balancing

namespace {

constexpr std::size_t n_measures = 2 + viseme_class_count;  // log frequency, syllables, viseme shares

// Running sums of one list.
struct ListSums {
    double frequency = 0.0;   // Σ sentence mean log frequency
    double syllables = 0.0;
    std::array<double, viseme_class_count> visemes{};
    double phones = 0.0;
    int n = 0;

    void add(const SentenceProfile& p, int sign) {
        frequency += sign * p.mean_log_frequency();
        syllables += sign * p.syllables;
        for (std::size_t c = 0; c < viseme_class_count; ++c) visemes[c] += sign * p.keyword_visemes[c];
        phones += sign * p.keyword_phones();
        n += sign;
    }
    std::array<double, n_measures> values() const {
        std::array<double, n_measures> v{};
        v[0] = n ? frequency / n : 0.0;
        v[1] = n ? syllables / n : 0.0;
        for (std::size_t c = 0; c < viseme_class_count; ++c) v[2 + c] = phones > 0 ? visemes[c] / phones : 0.0;
        return v;
    }
};

// What the cost compares with: per measure, the weight divided by the
// squared standard error of a list mean under random assignment (sentence
// SD² / list size), so each term is a weighted squared z-score; and the value
// over all candidates, which the test lists together should keep.
struct CostScales {
    std::array<double, n_measures> scale{};
    std::array<double, n_measures> target{};
};

CostScales measure_scales(const std::vector<SentenceProfile>& profiles, const std::vector<std::size_t>& candidates,
                          const BalanceSettings& s) {
    ListSums all;
    for (const auto i : candidates) all.add(profiles[i], +1);
    std::array<std::vector<double>, n_measures> values;
    for (const auto i : candidates) {
        const auto& p = profiles[i];
        values[0].push_back(p.mean_log_frequency());
        values[1].push_back(p.syllables);
        const double phones = p.keyword_phones();
        for (std::size_t c = 0; c < viseme_class_count; ++c)
            values[2 + c].push_back(phones > 0 ? p.keyword_visemes[c] / phones : 0.0);
    }
    CostScales c;
    c.target = all.values();
    for (std::size_t m = 0; m < n_measures; ++m) {
        const double w = m == 0 ? s.frequency_weight : m == 1 ? s.syllable_weight : s.viseme_weight;
        const double se2 = std::pow(sd(values[m]), 2) / std::max(1, s.sentences_per_list);
        c.scale[m] = se2 > 0 ? w / se2 : 0.0;
    }
    return c;
}

// Σ over lists and measures of the weighted squared z-score of the list
// value against the mean of the lists, plus (when candidates are left out)
// the z-score of that mean against all candidates, so the test set stays
// representative of the candidates (lists × the list term's scale: the
// standard error of a mean over every list).
double cost_of(const std::vector<ListSums>& sums, const CostScales& c) {
    const auto& scale = c.scale;
    const std::size_t lists = sums.size();
    std::vector<std::array<double, n_measures>> v(lists);
    std::array<double, n_measures> grand{};
    for (std::size_t l = 0; l < lists; ++l) {
        v[l] = sums[l].values();
        for (std::size_t m = 0; m < n_measures; ++m) grand[m] += v[l][m] / static_cast<double>(lists);
    }
    double cost = 0.0;
    for (std::size_t l = 0; l < lists; ++l)
        for (std::size_t m = 0; m < n_measures; ++m) cost += scale[m] * std::pow(v[l][m] - grand[m], 2);
    for (std::size_t m = 0; m < n_measures; ++m)
        cost += scale[m] * static_cast<double>(lists) * std::pow(grand[m] - c.target[m], 2);
    return cost;
}

void check_balance_settings(const BalanceSettings& s, std::size_t candidates) {
    if (s.lists < 1 || s.sentences_per_list < 1)
        throw InputError("", 0, 0, "lists", fmt::format("expected at least 1 list of at least 1 sentence, got {} × {}",
                                                        s.lists, s.sentences_per_list));
    if (s.restarts < 1 || s.iterations < 0)
        throw InputError("", 0, 0, "restarts",
                         fmt::format("expected restarts ≥ 1 and iterations ≥ 0, got {} and {}", s.restarts, s.iterations));
    const std::size_t needed = static_cast<std::size_t>(s.lists) * static_cast<std::size_t>(s.sentences_per_list);
    if (candidates < needed)
        throw InputError("", 0, 0, "list",
                         fmt::format("expected at least {} candidate test sentences ({} lists of {}), got {}", needed,
                                     s.lists, s.sentences_per_list, candidates));
}

// A seeded random assignment of the candidates: shuffled, the first
// lists × size in order into the lists, the rest unused.
ListAssignment random_assignment(const std::vector<std::size_t>& candidates, const BalanceSettings& s, Rng& rng) {
    std::vector<std::size_t> order = candidates;
    for (std::size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[rng.uniform_int(i)]);
    ListAssignment a;
    a.lists.resize(static_cast<std::size_t>(s.lists));
    std::size_t next = 0;
    for (auto& list : a.lists)
        for (int k = 0; k < s.sentences_per_list; ++k) list.push_back(order[next++]);
    a.unused.assign(order.begin() + static_cast<std::ptrdiff_t>(next), order.end());
    return a;
}

void sort_assignment(ListAssignment& a) {
    for (auto& l : a.lists) std::sort(l.begin(), l.end());
    std::sort(a.unused.begin(), a.unused.end());
}

}  // namespace

double balance_cost(const std::vector<SentenceProfile>& profiles, const std::vector<std::vector<std::size_t>>& lists,
                    const std::vector<std::size_t>& candidates, const BalanceSettings& settings) {
    const auto scale = measure_scales(profiles, candidates, settings);
    std::vector<ListSums> sums(lists.size());
    for (std::size_t l = 0; l < lists.size(); ++l)
        for (const auto i : lists[l]) sums[l].add(profiles[i], +1);
    return cost_of(sums, scale);
}

ListAssignment balance_lists(const std::vector<SentenceProfile>& profiles, const std::vector<std::size_t>& candidates,
                             const BalanceSettings& s) {
    check_balance_settings(s, candidates.size());
    const auto scale = measure_scales(profiles, candidates, s);
    const std::size_t lists = static_cast<std::size_t>(s.lists);
    const std::size_t per_list = static_cast<std::size_t>(s.sentences_per_list);
    const Rng base(s.seed);
    ListAssignment best;
    best.cost = std::numeric_limits<double>::infinity();
    Progress progress("balance", static_cast<std::size_t>(s.restarts));
    for (int r = 0; r < s.restarts; ++r) {
        Rng rng = base.derive(fmt::format("restart/{}", r));
        ListAssignment a = random_assignment(candidates, s, rng);
        // Slots: lists × size positions in lists, then the unused pool.
        std::vector<std::size_t> slot;
        for (const auto& l : a.lists) slot.insert(slot.end(), l.begin(), l.end());
        slot.insert(slot.end(), a.unused.begin(), a.unused.end());
        const std::size_t in_lists = lists * per_list;
        auto list_of = [&](std::size_t position) { return position < in_lists ? position / per_list : lists; };
        std::vector<ListSums> sums(lists);
        for (std::size_t k = 0; k < in_lists; ++k) sums[list_of(k)].add(profiles[slot[k]], +1);
        double cost = cost_of(sums, scale);
        std::vector<std::size_t> best_slot = slot;
        double best_cost = cost;
        // Simulated annealing: temperature falls geometrically from t0 to t1.
        const double t0 = 1.0, t1 = 1e-4;
        for (int it = 0; it < s.iterations; ++it) {
            const double temperature = t0 * std::pow(t1 / t0, static_cast<double>(it) / std::max(1, s.iterations - 1));
            const std::size_t x = rng.uniform_int(in_lists);
            const std::size_t y = rng.uniform_int(slot.size());
            const std::size_t lx = list_of(x), ly = list_of(y);
            if (lx == ly) continue;
            sums[lx].add(profiles[slot[x]], -1);
            sums[lx].add(profiles[slot[y]], +1);
            if (ly < lists) {
                sums[ly].add(profiles[slot[y]], -1);
                sums[ly].add(profiles[slot[x]], +1);
            }
            const double proposed = cost_of(sums, scale);
            const double delta = proposed - cost;
            if (delta <= 0.0 || rng.uniform() < std::exp(-delta / temperature)) {
                std::swap(slot[x], slot[y]);
                cost = proposed;
                if (cost < best_cost) {
                    best_cost = cost;
                    best_slot = slot;
                }
            } else {
                sums[lx].add(profiles[slot[y]], -1);
                sums[lx].add(profiles[slot[x]], +1);
                if (ly < lists) {
                    sums[ly].add(profiles[slot[x]], -1);
                    sums[ly].add(profiles[slot[y]], +1);
                }
            }
        }
        if (best_cost < best.cost) {
            best.cost = best_cost;
            best.lists.assign(lists, {});
            for (std::size_t k = 0; k < in_lists; ++k) best.lists[list_of(k)].push_back(best_slot[k]);
            best.unused.assign(best_slot.begin() + static_cast<std::ptrdiff_t>(in_lists), best_slot.end());
        }
        progress.advance();
    }
    progress.finish();
    sort_assignment(best);
    // Recompute from scratch (the running sums drift by rounding).
    best.cost = balance_cost(profiles, best.lists, candidates, s);
    return best;
}

OneWayAnova one_way_anova(const std::vector<std::vector<double>>& groups) {
    OneWayAnova a;
    std::vector<double> all;
    for (const auto& g : groups) all.insert(all.end(), g.begin(), g.end());
    const double grand = mean(all);
    double between = 0.0, within = 0.0;
    int k = 0;
    for (const auto& g : groups) {
        if (g.empty()) continue;
        ++k;
        const double m = mean(g);
        between += static_cast<double>(g.size()) * (m - grand) * (m - grand);
        for (double x : g) within += (x - m) * (x - m);
    }
    a.df_between = k - 1;
    a.df_within = static_cast<int>(all.size()) - k;
    if (a.df_between < 1 || a.df_within < 1) return a;
    const double ms_between = between / a.df_between, ms_within = within / a.df_within;
    if (ms_within <= 0.0) {
        a.f = ms_between > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
        a.p = ms_between > 0.0 ? 0.0 : 1.0;
        return a;
    }
    a.f = ms_between / ms_within;
    a.p = boost::math::cdf(boost::math::complement(boost::math::fisher_f(a.df_between, a.df_within), a.f));
    return a;
}

namespace {

struct ListStats {
    std::vector<double> keyword_frequency;  // every keyword of the list
    std::vector<double> syllables;
    std::array<double, viseme_class_count> visemes{};
    double phones = 0.0;
};

ListStats stats_of(const std::vector<SentenceProfile>& profiles, const std::vector<std::size_t>& list) {
    ListStats s;
    for (const auto i : list) {
        const auto& p = profiles[i];
        s.keyword_frequency.insert(s.keyword_frequency.end(), p.keyword_log_frequency.begin(),
                                   p.keyword_log_frequency.end());
        s.syllables.push_back(p.syllables);
        for (std::size_t c = 0; c < viseme_class_count; ++c) s.visemes[c] += p.keyword_visemes[c];
        s.phones += p.keyword_phones();
    }
    return s;
}

std::string format_p(double p) { return p < 0.001 ? "< 0.001" : fmt::format("{:.3f}", p); }

// The across-list comparison of one assignment (Markdown lines).
std::string comparison(const std::vector<SentenceProfile>& profiles, const std::vector<std::vector<std::size_t>>& lists) {
    std::vector<ListStats> stats;
    for (const auto& l : lists) stats.push_back(stats_of(profiles, l));
    std::vector<std::vector<double>> freq, syl;
    for (const auto& s : stats) {
        freq.push_back(s.keyword_frequency);
        syl.push_back(s.syllables);
    }
    auto range_of_means = [](const std::vector<std::vector<double>>& g) {
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (const auto& x : g) {
            lo = std::min(lo, mean(x));
            hi = std::max(hi, mean(x));
        }
        return hi - lo;
    };
    const OneWayAnova fa = one_way_anova(freq), sa = one_way_anova(syl);
    // χ² test of homogeneity of the lists × classes table of keyword phone counts.
    double total = 0.0;
    std::array<double, viseme_class_count> column{};
    for (const auto& s : stats) {
        total += s.phones;
        for (std::size_t c = 0; c < viseme_class_count; ++c) column[c] += s.visemes[c];
    }
    double chi2 = 0.0, max_share_diff = 0.0;
    std::size_t used_classes = 0;
    for (std::size_t c = 0; c < viseme_class_count; ++c) {
        if (column[c] <= 0) continue;
        ++used_classes;
        double lo = 1.0, hi = 0.0;
        for (const auto& s : stats) {
            const double expected = s.phones * column[c] / total;
            if (expected > 0) chi2 += std::pow(s.visemes[c] - expected, 2) / expected;
            const double share = s.phones > 0 ? s.visemes[c] / s.phones : 0.0;
            lo = std::min(lo, share);
            hi = std::max(hi, share);
        }
        max_share_diff = std::max(max_share_diff, hi - lo);
    }
    const int chi_df = static_cast<int>((stats.size() - 1) * (used_classes - 1));
    const double chi_p =
        chi_df > 0 ? boost::math::cdf(boost::math::complement(boost::math::chi_squared(chi_df), chi2)) : 1.0;
    std::string out;
    out += fmt::format("| keyword log10 frequency (keywords) | F({}, {}) = {:.3f}, p = {} | {:.3f} |\n", fa.df_between,
                       fa.df_within, fa.f, format_p(fa.p), range_of_means(freq));
    out += fmt::format("| syllables (sentences) | F({}, {}) = {:.3f}, p = {} | {:.3f} |\n", sa.df_between, sa.df_within,
                       sa.f, format_p(sa.p), range_of_means(syl));
    out += fmt::format("| keyword viseme classes (phone counts) | χ²({}) = {:.2f}, p = {} | {:.1f} percentage points |\n",
                       chi_df, chi2, format_p(chi_p), 100.0 * max_share_diff);
    return out;
}

}  // namespace

std::string balance_report(const Corpus& corpus, const std::vector<SentenceProfile>& profiles,
                           const ListAssignment& assignment, const BalanceSettings& s,
                           const std::string& command_line) {
    std::string out;
    out += fmt::format("# Test-list balance of `{}`\n\n", corpus.path.filename().string());
    out += fmt::format(
        "Written by `{}`. {} test lists of {} sentences chosen from {} candidates by a seeded search "
        "(simulated annealing over swaps, seed {}, {} starts × {} proposals; cost {:.3f} = Σ weighted squared "
        "z-scores of the list means against their mean and of that mean against all candidates, weights: frequency {}, syllables {}, each viseme class {}).\n\n",
        command_line, s.lists, s.sentences_per_list,
        std::accumulate(assignment.lists.begin(), assignment.lists.end(), assignment.unused.size(),
                        [](std::size_t n, const auto& l) { return n + l.size(); }),
        s.seed, s.restarts, s.iterations, assignment.cost, s.frequency_weight, s.syllable_weight, s.viseme_weight);
    out += "Measures: *syllables* = vowel phones of the espeak-ng rendering (voice " + s.profile.voice +
           "); *keyword log10 frequency* = log10(1 + SemCor tag count of the keyword's lemma) from "
           "`protocols/corpus/word-frequency.tsv` (WordNet 3.0, 0 for words not in WordNet); *viseme shares* = "
           "share of the keywords' phones (each keyword spoken alone) per visual class: bilabial P B M; "
           "labiodental F V; dental TH DH; rounded (rounded or protruded lips) W R SH ZH CH JH OW UW UH AO OY AW ER; "
           "open vowel AA AE AY; spread vowel AH EH EY IH IY; lingual (neutral lips) T D N S Z L K G NG HH Y.\n\n";

    out += "## Per list\n\n| list | sentences | keyword log10 freq. mean (SD) | syllables mean (SD) |";
    for (std::size_t c = 0; c < viseme_class_count; ++c) out += fmt::format(" {} % |", to_string(VisemeClass(c)));
    out += "\n|---|---|---|---|";
    for (std::size_t c = 0; c < viseme_class_count; ++c) out += "---|";
    out += "\n";
    auto row = [&](const std::string& name, const std::vector<std::size_t>& list) {
        const ListStats st = stats_of(profiles, list);
        std::string r = fmt::format("| {} | {} | {:.3f} ({:.3f}) | {:.2f} ({:.2f}) |", name, list.size(),
                                    mean(st.keyword_frequency), sd(st.keyword_frequency), mean(st.syllables),
                                    sd(st.syllables));
        for (std::size_t c = 0; c < viseme_class_count; ++c)
            r += fmt::format(" {:.1f} |", st.phones > 0 ? 100.0 * st.visemes[c] / st.phones : 0.0);
        return r + "\n";
    };
    for (std::size_t l = 0; l < assignment.lists.size(); ++l) out += row(std::to_string(l + 1), assignment.lists[l]);
    std::vector<std::size_t> all_test;
    for (const auto& l : assignment.lists) all_test.insert(all_test.end(), l.begin(), l.end());
    out += row("all test", all_test);
    if (!assignment.unused.empty()) {
        std::vector<std::size_t> all_candidates = all_test;
        all_candidates.insert(all_candidates.end(), assignment.unused.begin(), assignment.unused.end());
        out += row("all candidates", all_candidates);
    }
    for (const std::string mark : {"warmup", "practice"}) {
        std::vector<std::size_t> marked;
        for (std::size_t i = 0; i < corpus.sentences.size(); ++i)
            if (corpus.sentences[i].list == mark) marked.push_back(i);
        if (!marked.empty()) out += row(mark + " (not balanced)", marked);
    }
    if (!assignment.unused.empty()) out += row("unused", assignment.unused);

    out += "\n## Across the test lists\n\n| measure | test | largest difference between list means |\n|---|---|---|\n";
    out += comparison(profiles, assignment.lists);
    std::vector<std::size_t> candidates = all_test;
    candidates.insert(candidates.end(), assignment.unused.begin(), assignment.unused.end());
    std::sort(candidates.begin(), candidates.end());
    Rng rng = Rng(s.seed).derive("report/random-assignment");
    ListAssignment random = random_assignment(candidates, s, rng);
    out += fmt::format(
        "\nFor comparison, a seeded random assignment of the same candidates (cost {:.3f}):\n\n"
        "| measure | test | largest difference between list means |\n|---|---|---|\n",
        balance_cost(profiles, random.lists, candidates, s));
    out += comparison(profiles, random.lists);

    out += "\n## Sentences\n\n| list | id | syllables | keywords (log10 freq.) | text |\n|---|---|---|---|---|\n";
    std::vector<std::pair<std::string, std::size_t>> order;
    for (std::size_t l = 0; l < assignment.lists.size(); ++l)
        for (const auto i : assignment.lists[l]) order.emplace_back(std::to_string(l + 1), i);
    for (std::size_t i = 0; i < corpus.sentences.size(); ++i)
        if (corpus.sentences[i].list == "warmup" || corpus.sentences[i].list == "practice")
            order.emplace_back(corpus.sentences[i].list, i);
    for (const auto i : assignment.unused) order.emplace_back("unused", i);
    for (const auto& [name, i] : order) {
        const auto& sentence = corpus.sentences[i];
        std::string kws;
        for (std::size_t k = 0; k < sentence.keywords.size(); ++k)
            kws += fmt::format("{}{} ({:.2f})", k ? ", " : "", sentence.keywords[k].word,
                               profiles[i].keyword_log_frequency[k]);
        out += fmt::format("| {} | {} | {} | {} | {} |\n", name, sentence.id, profiles[i].syllables, kws, sentence.text);
    }
    std::string outside;
    for (std::size_t i = 0; i < corpus.sentences.size(); ++i)
        if (profiles[i].syllables < s.min_syllables || profiles[i].syllables > s.max_syllables)
            outside += fmt::format("- {} ({} syllables): {}\n", corpus.sentences[i].id, profiles[i].syllables,
                                   corpus.sentences[i].text);
    out += fmt::format("\n## Syllable range {}–{}\n\n", s.min_syllables, s.max_syllables);
    out += outside.empty() ? "Every sentence is in range.\n" : "Outside the range:\n\n" + outside;
    return out;
}

BalanceOutcome balance_corpus(const Corpus& corpus, const BalanceSettings& s, const WordTable& words) {
    BalanceOutcome o;
    o.corpus = corpus;
    std::vector<std::size_t> candidates;
    DiagnosticList problems;
    for (std::size_t i = 0; i < corpus.sentences.size(); ++i) {
        const auto& sentence = corpus.sentences[i];
        if (sentence.list == "warmup" || sentence.list == "practice") continue;
        if (!sentence.list.empty() && !parse_int(sentence.list))
            problems.add(corpus.path.string(), sentence.line, 0, "list",
                         fmt::format("expected a list number, \"warmup\", \"practice\" or empty, got \"{}\"",
                                     sentence.list));
        candidates.push_back(i);
    }
    problems.throw_if_any();
    try {
        check_balance_settings(s, candidates.size());
    } catch (const InputError& e) {
        throw InputError(corpus.path.string(), 0, 0, e.first().field, e.first().message);
    }
    Progress progress("profile sentences", corpus.sentences.size());
    for (const auto& sentence : corpus.sentences) {
        o.profiles.push_back(profile_sentence(sentence, words, s.profile));
        progress.advance();
    }
    progress.finish();
    o.assignment = balance_lists(o.profiles, candidates, s);
    for (const auto i : candidates) o.corpus.sentences[i].list.clear();
    for (std::size_t l = 0; l < o.assignment.lists.size(); ++l)
        for (const auto i : o.assignment.lists[l]) o.corpus.sentences[i].list = std::to_string(l + 1);
    return o;
}

// ------------------------------------------------------------------ import

namespace {

// "noun, verb" for the WordNet letters "nv" (each once, in nvar order).
std::string pos_names(const std::string& letters) {
    std::string out;
    for (const auto& [letter, name] : {std::pair{'n', "noun"}, {'v', "verb"}, {'a', "adjective"}, {'r', "adverb"}})
        if (letters.find(letter) != std::string::npos) out += (out.empty() ? "" : ", ") + std::string(name);
    return out;
}

}  // namespace

std::vector<ListedSentence> read_sentence_lines(const std::filesystem::path& path) {
    // "List 3", "## List 3", "Harvard list 3:", "LIST 03."
    static const std::regex heading(R"(^#*\s*(?:[A-Za-z][A-Za-z ]*\s)?list\s+0*(\d+)\s*[:.]?\s*$)",
                                    std::regex::icase);
    // "1.", "1)", "(1)", "[1]", "1:", "1<TAB>", "-", "*", "•" before the sentence.
    static const std::regex numbering(R"(^(\(\d+\)|\[\d+\]|\d+[.):]|\d+\t|[-*]|\xE2\x80\xA2)\s*)");
    // A Markdown rule or heading underline ("---", "***", "===").
    static const std::regex rule(R"(^[-*_=\s]{3,}$)");
    const std::string file = path.string();
    std::istringstream in(read_text_file(path));
    std::vector<ListedSentence> out;
    std::string line, list;
    int number = 0;
    long long last_item = 0;  // the last item number in the current list (0: none yet)
    int last_item_line = 0;
    while (std::getline(in, line)) {
        ++number;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        const std::string trimmed = trim(line);
        if (trimmed.empty()) continue;
        std::smatch m;
        if (std::regex_match(trimmed, m, heading)) {
            list = m[1].str();
            last_item = 0;
            continue;
        }
        if (trimmed[0] == '#' || std::regex_match(trimmed, rule)) continue;
        ListedSentence s;
        s.line = number;
        s.list = list;
        std::string text = trimmed;
        if (std::regex_search(text, m, numbering) && m.position(0) == 0) {
            s.numbering = trim(m[1].str());
            text = text.substr(static_cast<std::size_t>(m.length(0)));
            if (trim(text).empty())
                throw InputError(file, number, 1, "sentence",
                                 fmt::format("expected a sentence after the numbering \"{}\", got nothing", s.numbering));
            // Item numbers rise within a list; a repeated or falling number is
            // a pasted or misplaced line (a list may start again at 1).
            const std::string digits = std::regex_replace(s.numbering, std::regex(R"(\D)"), "");
            if (const auto item = digits.empty() ? std::nullopt : parse_int(digits)) {
                if (last_item > 0 && *item <= last_item && *item != 1)
                    throw InputError(file, number, 1, "numbering",
                                     fmt::format("expected an item number above {} (line {}{}), got {}; a new list "
                                                 "starts at 1 or with a heading such as \"List 2\"",
                                                 last_item, last_item_line,
                                                 list.empty() ? std::string() : fmt::format(", list {}", list), *item));
                last_item = *item;
                last_item_line = number;
            }
        }
        s.text = trim(text);
        out.push_back(std::move(s));
    }
    if (out.empty()) throw InputError(path, "expected one sentence a line, got no sentences");
    return out;
}

std::vector<std::string> read_sentence_list(const std::filesystem::path& path) {
    std::vector<std::string> out;
    for (const auto& s : read_sentence_lines(path)) out.push_back(s.text);
    return out;
}

ImportOutcome import_sentences(const std::vector<std::string>& texts, const ImportSettings& s, const WordTable& words) {
    std::vector<ListedSentence> sentences;
    for (std::size_t i = 0; i < texts.size(); ++i) sentences.push_back({texts[i], "", static_cast<int>(i + 1), ""});
    return import_listed_sentences(sentences, s, words);
}

ImportOutcome import_listed_sentences(const std::vector<ListedSentence>& listed, const ImportSettings& s,
                                      const WordTable& words) {
    std::vector<std::string> texts;
    for (const auto& l : listed) texts.push_back(l.text);
    if (s.keywords < 1) throw InputError("", 0, 0, "keywords", fmt::format("expected ≥ 1 keyword, got {}", s.keywords));
    ImportOutcome o;
    const bool count = s.min_syllables > 0 || s.max_syllables > 0;
    const int digits = std::max(3, static_cast<int>(std::to_string(texts.size()).size()));
    Progress progress("import", texts.size());
    std::size_t complete = 0, out_of_range = 0;
    for (std::size_t t = 0; t < texts.size(); ++t) {
        ImportedSentence r;
        r.sentence.id = fmt::format("{}{:0{}}", s.id_prefix, t + 1, digits);
        r.sentence.text = texts[t];
        r.sentence.line = listed[t].line;
        r.sentence.list = listed[t].list;
        if (!listed[t].numbering.empty())
            r.notes.push_back(fmt::format("line {}: numbering \"{}\" removed", listed[t].line, listed[t].numbering));
        // Rank 0: noun/verb/adjective; 1: adverb only; 2: not in WordNet; function words are skipped.
        struct Candidate {
            std::size_t position;
            std::string word;
            int rank;
            std::optional<double> zipf;  // frequency; nullopt: unknown (ranked as rarest)
            std::string pos;             // "noun, verb" …
        };
        std::vector<Candidate> candidates;
        std::set<std::string> seen;
        const auto ws = text_words(texts[t]);
        for (std::size_t w = 0; w < ws.size(); ++w) {
            const std::string key = ascii_lower(ws[w]);
            if (words.is_function_word(key)) {
                r.notes.push_back(fmt::format("{}: function word", ws[w]));
                continue;
            }
            if (!seen.insert(key).second) {
                r.notes.push_back(fmt::format("{}: repeated, used once", ws[w]));
                continue;
            }
            const auto found = words.lookup(key);
            std::string pos;
            for (const auto& f : found) pos += f.pos;
            const bool nva = pos.find_first_of("nva") != std::string::npos;
            const int rank = found.empty() ? 2 : nva ? 0 : 1;
            candidates.push_back({w, ws[w], rank, words.zipf(key), pos_names(pos)});
        }
        std::vector<Candidate> ranked = candidates;
        std::stable_sort(ranked.begin(), ranked.end(), [](const Candidate& a, const Candidate& b) {
            if (a.rank != b.rank) return a.rank < b.rank;
            const double za = a.zipf.value_or(0.0), zb = b.zipf.value_or(0.0);
            if (za != zb) return za < zb;
            return a.position < b.position;
        });
        const std::size_t n = std::min<std::size_t>(ranked.size(), static_cast<std::size_t>(s.keywords));
        std::vector<Candidate> chosen(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(n));
        std::sort(chosen.begin(), chosen.end(), [](const Candidate& a, const Candidate& b) { return a.position < b.position; });

        for (const auto& c : ranked) {
            const bool taken = std::any_of(chosen.begin(), chosen.end(),
                                           [&](const Candidate& k) { return k.position == c.position; });
            const std::string what = c.rank == 2 ? "not in WordNet, taken as a content word"
                                                 : "content word (WordNet: " + c.pos + ")";
            r.notes.push_back(fmt::format("{}: {}, {}: {}", c.word, what,
                                          c.zipf ? fmt::format("Zipf {:.2f}", *c.zipf)
                                                 : std::string("frequency unknown (ranked as rarest)"),
                                          taken ? "keyword" : "not chosen (better-ranked or rarer words filled the slots)"));
        }
        for (const auto& c : chosen) r.sentence.keywords.push_back({c.word, {}});
        // Proposed alternates: for review, not accepted here.
        if (s.alternates) {
            std::string review;
            for (const auto& c : chosen) {
                const auto proposals = s.alternates(ascii_lower(c.word));
                if (proposals.empty()) continue;
                std::string forms, reasons;
                for (const auto& p : proposals) {
                    forms += "|" + p.word;
                    reasons += fmt::format("{}{} ({})", reasons.empty() ? "" : ", ", p.word, p.reason);
                }
                review += (review.empty() ? "" : ";") + c.word + forms;
                r.notes.push_back(fmt::format("{}: proposed alternates, to review: {}", c.word, reasons));
            }
            r.sentence.review = review;
        }
        r.complete = static_cast<int>(n) == s.keywords;
        complete += r.complete;
        if (count) {
            r.syllables = count_syllables(texts[t], s.voice);
            out_of_range += r.syllables < s.min_syllables || r.syllables > s.max_syllables;
        }
        if (!r.sentence.keywords.empty()) o.corpus.sentences.push_back(r.sentence);
        o.sentences.push_back(std::move(r));
        progress.advance();
    }
    progress.finish();

    std::string& rep = o.report;
    for (const auto& r : o.sentences) {
        std::string kws;
        for (const auto& k : r.sentence.keywords) kws += (kws.empty() ? "" : ";") + k.word;
        rep += fmt::format("{} \"{}\"\n  keywords: {}{}\n", r.sentence.id, r.sentence.text, kws.empty() ? "(none)" : kws,
                           r.complete ? "" : fmt::format("  <- only {} of {}: check by hand", r.sentence.keywords.size(),
                                                         s.keywords));
        if (count)
            rep += fmt::format("  syllables: {}{}\n", r.syllables,
                               r.syllables < s.min_syllables || r.syllables > s.max_syllables
                                   ? fmt::format("  <- outside {}–{}", s.min_syllables, s.max_syllables)
                                   : "");
        for (const auto& n : r.notes) rep += "    " + n + "\n";
    }
    rep += fmt::format("\n{} sentences: {} with {} keywords, {} with fewer", o.sentences.size(), complete, s.keywords,
                       o.sentences.size() - complete);
    std::size_t none = o.sentences.size() - o.corpus.sentences.size();
    if (none) rep += fmt::format(" ({} with none, left out of the corpus)", none);
    if (count) rep += fmt::format(", {} outside {}–{} syllables", out_of_range, s.min_syllables, s.max_syllables);
    rep += ".\n";
    if (s.alternates) {
        std::size_t proposed = 0;
        for (const auto& r : o.sentences) proposed += !r.sentence.review.empty();
        rep += fmt::format("Alternates proposed for {} sentences (inflections and spelling variants) are in the "
                           "`review` column, not in the keywords: check each and move the ones to accept into "
                           "`keywords` as keyword|alternate.\n",
                           proposed);
    } else {
        rep += "No alternates are proposed; add accepted forms by hand as keyword|alternate.\n";
    }
    std::size_t numbered = 0;
    std::set<std::string> lists;
    for (const auto& l : listed) {
        numbered += !l.numbering.empty();
        if (!l.list.empty()) lists.insert(l.list);
    }
    if (numbered) rep += fmt::format("Numbering removed from {} lines.\n", numbered);
    if (!lists.empty())
        rep += fmt::format("List headings set the list column: {} list{}.\n", lists.size(), lists.size() == 1 ? "" : "s");
    if (o.corpus.sentences.empty()) throw InputError("", 0, 0, "sentences", "expected sentences with content words, got none");
    return o;
}

}  // namespace avsi
