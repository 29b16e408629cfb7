// Seeded balanced assignment of test lists and its report (list_balance.h):
// simulated annealing over swaps of sentences between lists and with the
// unused candidates, minimising weighted squared z-scores of the list means;
// the report's one-way ANOVA and chi-squared tests across the lists.
#include "avsi/core/list_balance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"

namespace avsi {

namespace {

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
std::string comparison(const std::vector<SentenceProfile>& profiles, const std::vector<std::vector<std::size_t>>& lists,
                       bool frequency) {
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
    if (frequency)
        out += fmt::format("| keyword log10 frequency (keywords) | F({}, {}) = {:.3f}, p = {} | {:.3f} |\n",
                           fa.df_between, fa.df_within, fa.f, format_p(fa.p), range_of_means(freq));
    out += fmt::format("| syllables (sentences) | F({}, {}) = {:.3f}, p = {} | {:.3f} |\n", sa.df_between, sa.df_within,
                       sa.f, format_p(sa.p), range_of_means(syl));
    out += fmt::format("| keyword viseme classes (phone counts) | χ²({}) = {:.2f}, p = {} | {:.1f} percentage points |\n",
                       chi_df, chi2, format_p(chi_p), 100.0 * max_share_diff);
    return out;
}

// The report's paragraph on what is measured.
std::string measures_text(const BalanceSettings& s) {
    std::string out = "Measures: *syllables* = vowel phones of the espeak-ng rendering (voice " + s.profile.voice + "); ";
    if (s.profile.keyword_frequency)
        return out + "*keyword log10 frequency* = log10(1 + SemCor tag count of the keyword's lemma) from "
                     "`protocols/corpus/word-frequency.tsv` (WordNet 3.0, 0 for words not in WordNet); *viseme shares* = "
                     "share of the keywords' phones (each keyword spoken alone) per visual class: bilabial P B M; "
                     "labiodental F V; dental TH DH; rounded (rounded or protruded lips) W R SH ZH CH JH OW UW UH AO OY "
                     "AW ER; open vowel AA AE AY; spread vowel AH EH EY IH IY; lingual (neutral lips) T D N S Z L K G "
                     "NG HH Y.\n\n";
    return out + "*viseme shares* = share of the keywords' phones (each keyword spoken alone) per visual class, "
                 "from each phone's features in the voice's language table (first that applies): labiodental, "
                 "dental, bilabial (lips closed, not rounded), rounded (rounded or protruded lips ≥ 0.5), open "
                 "vowel (open 1), spread vowel (other vowels), lingual (other consonants). No keyword frequency: "
                 "the frequency counts (SemCor) are English's, and this voice's language has none.\n\n";
}

// The per-list table's header.
std::string per_list_header(bool frequency) {
    std::string out = "## Per list\n\n| list | sentences |";
    if (frequency) out += " keyword log10 freq. mean (SD) |";
    out += " syllables mean (SD) |";
    for (std::size_t c = 0; c < viseme_class_count; ++c) out += fmt::format(" {} % |", to_string(VisemeClass(c)));
    out += frequency ? "\n|---|---|---|---|" : "\n|---|---|---|";
    for (std::size_t c = 0; c < viseme_class_count; ++c) out += "---|";
    return out + "\n";
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
    out += measures_text(s);
    const bool frequency = s.profile.keyword_frequency;
    out += per_list_header(frequency);
    auto row = [&](const std::string& name, const std::vector<std::size_t>& list) {
        const ListStats st = stats_of(profiles, list);
        std::string r = fmt::format("| {} | {} |", name, list.size());
        if (frequency) r += fmt::format(" {:.3f} ({:.3f}) |", mean(st.keyword_frequency), sd(st.keyword_frequency));
        r += fmt::format(" {:.2f} ({:.2f}) |", mean(st.syllables), sd(st.syllables));
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
    out += comparison(profiles, assignment.lists, frequency);
    std::vector<std::size_t> candidates = all_test;
    candidates.insert(candidates.end(), assignment.unused.begin(), assignment.unused.end());
    std::sort(candidates.begin(), candidates.end());
    Rng rng = Rng(s.seed).derive("report/random-assignment");
    ListAssignment random = random_assignment(candidates, s, rng);
    out += fmt::format(
        "\nFor comparison, a seeded random assignment of the same candidates (cost {:.3f}):\n\n"
        "| measure | test | largest difference between list means |\n|---|---|---|\n",
        balance_cost(profiles, random.lists, candidates, s));
    out += comparison(profiles, random.lists, frequency);

    out += fmt::format("\n## Sentences\n\n| list | id | syllables | keywords{} | text |\n|---|---|---|---|---|\n",
                       frequency ? " (log10 freq.)" : "");
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
            kws += frequency ? fmt::format("{}{} ({:.2f})", k ? ", " : "", sentence.keywords[k].word,
                                           profiles[i].keyword_log_frequency[k])
                             : fmt::format("{}{}", k ? ", " : "", sentence.keywords[k].word);
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

}  // namespace avsi
