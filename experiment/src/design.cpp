// Counterbalanced design (see design.h).
#include "avsi/experiment/design.h"

#include <algorithm>
#include <map>
#include <numeric>
#include <set>

#include <fmt/format.h>

#include "avsi/analysis/adaptive.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"

namespace avsi::experiment {

namespace {

// Fisher-Yates with our platform-independent generator.
template <typename T>
void shuffle(std::vector<T>& items, Rng& rng) {
    for (std::size_t i = items.size(); i > 1; --i) {
        const std::size_t j = static_cast<std::size_t>(rng.uniform_int(i));
        std::swap(items[i - 1], items[j]);
    }
}

Rng subject_rng(const DesignSettings& design, int subject, const std::string& stream) {
    return Rng(design.seed).derive(fmt::format("subject/{}/{}", subject, stream));
}

}  // namespace

std::string to_string(Phase phase) {
    switch (phase) {
        case Phase::Warmup: return "warmup";
        case Phase::Practice: return "practice";
        case Phase::Test: return "test";
    }
    return "?";
}

bool parse_phase(const std::string& text, Phase& phase) {
    if (text == "warmup") phase = Phase::Warmup;
    else if (text == "practice") phase = Phase::Practice;
    else if (text == "test") phase = Phase::Test;
    else return false;
    return true;
}

ListAssignment assign_lists(const Corpus& corpus, const DesignSettings& design) {
    const std::string file = corpus.path.string();
    ListAssignment out;
    out.lists.resize(static_cast<std::size_t>(design.lists));
    const bool has_lists = std::any_of(corpus.sentences.begin(), corpus.sentences.end(),
                                       [](const Sentence& s) { return !s.list.empty(); });
    DiagnosticList problems;
    if (has_lists) {
        int unused = 0;
        for (const Sentence& s : corpus.sentences) {
            if (s.list.empty()) {
                ++unused;
                continue;
            }
            if (s.list == "warmup") {
                out.warmup.push_back(s.id);
                continue;
            }
            if (s.list == "practice") {
                out.practice.push_back(s.id);
                continue;
            }
            const auto n = parse_int(s.list);
            if (!n || *n < 1 || *n > design.lists) {
                problems.add(file, s.line, 0, "list",
                             fmt::format("expected a list number in [1, {}], \"practice\" or "
                                         "\"warmup\", got \"{}\"",
                                         design.lists, s.list));
                continue;
            }
            out.lists[static_cast<std::size_t>(*n - 1)].push_back(s.id);
        }
        for (int l = 0; l < design.lists; ++l) {
            const auto size = static_cast<int>(out.lists[static_cast<std::size_t>(l)].size());
            if (size != design.sentences_per_list)
                problems.add(file, 0, 0, "list",
                             fmt::format("list {} has {} sentences, the protocol's "
                                         "design.sentences_per_list is {}",
                                         l + 1, size, design.sentences_per_list));
        }
        if (static_cast<int>(out.warmup.size()) != design.warmup)
            problems.add(file, 0, 0, "list",
                         fmt::format("{} sentences are marked \"warmup\", the protocol's design.warmup is {}",
                                     out.warmup.size(), design.warmup));
        if (static_cast<int>(out.practice.size()) != design.practice)
            problems.add(file, 0, 0, "list",
                         fmt::format("{} sentences are marked \"practice\", the protocol's design.practice is {}",
                                     out.practice.size(), design.practice));
        problems.throw_if_any();
        if (unused > 0) log_info("design: {} sentences of {} have no list and are not used", unused, file);
        return out;
    }
    // No list column: a seeded assignment into equal-size lists.
    const int needed = design.warmup + design.practice + design.lists * design.sentences_per_list;
    const int available = static_cast<int>(corpus.sentences.size());
    if (available < needed)
        throw InputError(file, 0, 0, "",
                         fmt::format("the design needs {} sentences ({} warm-up + {} practice + {} lists "
                                     "× {}), the corpus has {}",
                                     needed, design.warmup, design.practice, design.lists,
                                     design.sentences_per_list, available));
    std::vector<std::string> ids;
    for (const Sentence& s : corpus.sentences) ids.push_back(s.id);
    Rng rng = Rng(design.seed).derive("lists");
    shuffle(ids, rng);
    std::size_t next = 0;
    for (int i = 0; i < design.warmup; ++i) out.warmup.push_back(ids[next++]);
    for (int i = 0; i < design.practice; ++i) out.practice.push_back(ids[next++]);
    for (int l = 0; l < design.lists; ++l)
        for (int i = 0; i < design.sentences_per_list; ++i)
            out.lists[static_cast<std::size_t>(l)].push_back(ids[next++]);
    // Keep corpus order within each list so the assignment reads naturally.
    auto corpus_order = [&](std::vector<std::string>& v) {
        std::map<std::string, std::size_t> index;
        for (std::size_t i = 0; i < corpus.sentences.size(); ++i) index[corpus.sentences[i].id] = i;
        std::sort(v.begin(), v.end(), [&](const auto& a, const auto& b) { return index[a] < index[b]; });
    };
    corpus_order(out.warmup);
    corpus_order(out.practice);
    for (auto& l : out.lists) corpus_order(l);
    if (next < ids.size())
        log_info("design: {} sentences of {} are not needed by the design and are not used",
                 ids.size() - next, file);
    return out;
}

std::vector<std::vector<int>> williams_design(int k) {
    AVSI_ASSERT(k >= 1);
    // First row 0, 1, k−1, 2, k−2, …; row r adds r (mod k) to every entry.
    std::vector<int> first;
    for (int i = 0, lo = 1, hi = k - 1; i < k; ++i) {
        if (i == 0) first.push_back(0);
        else if (i % 2 == 1) first.push_back(lo++);
        else first.push_back(hi--);
    }
    std::vector<std::vector<int>> rows;
    for (int r = 0; r < k; ++r) {
        std::vector<int> row;
        for (int v : first) row.push_back((v + r) % k);
        rows.push_back(row);
    }
    if (k % 2 == 1) {
        // Odd k: the mirror image of each row balances the neighbour pairs.
        for (int r = 0; r < k; ++r) {
            std::vector<int> row = rows[static_cast<std::size_t>(r)];
            std::reverse(row.begin(), row.end());
            rows.push_back(row);
        }
    }
    return rows;
}

std::vector<int> condition_order(const DesignSettings& design, int k, int subject) {
    if (design.counterbalance == Counterbalance::Williams) {
        const auto rows = williams_design(k);
        // One seeded relabelling per experiment keeps the balance of the square.
        std::vector<int> labels(static_cast<std::size_t>(k));
        std::iota(labels.begin(), labels.end(), 0);
        Rng rng = Rng(design.seed).derive("williams/labels");
        shuffle(labels, rng);
        const auto& row = rows[static_cast<std::size_t>((subject - 1) % static_cast<int>(rows.size()))];
        std::vector<int> order;
        for (int v : row) order.push_back(labels[static_cast<std::size_t>(v)]);
        return order;
    }
    std::vector<int> order(static_cast<std::size_t>(k));
    std::iota(order.begin(), order.end(), 0);
    Rng rng = subject_rng(design, subject, "condition-order");
    shuffle(order, rng);
    return order;
}

int paired_condition(int list_index, int subject, int k) { return (list_index + subject - 1) % k; }

std::vector<PlannedTrial> design_subject(const Protocol& protocol, const ListAssignment& lists,
                                         int subject) {
    AVSI_ASSERT(subject >= 1);
    const DesignSettings& design = protocol.design;
    const int k = static_cast<int>(protocol.conditions.size());
    AVSI_ASSERT(k >= 1 && static_cast<int>(lists.lists.size()) == k);
    std::vector<PlannedTrial> trials;
    auto add = [&](Phase phase, int block, const std::string& list, const std::string& condition,
                   const std::string& sentence) {
        PlannedTrial t;
        t.subject = subject;
        t.position = static_cast<int>(trials.size()) + 1;
        t.phase = phase;
        t.block = block;
        t.list = list;
        t.condition = condition;
        t.sentence = sentence;
        t.stimulus = sentence + "/" + condition + ".mp4";
        trials.push_back(std::move(t));
    };
    const std::vector<int> order = condition_order(design, k, subject);

    const std::string warmup_condition =
        design.warmup_condition.empty() ? protocol.conditions.front().name : design.warmup_condition;
    for (const auto& id : lists.warmup) add(Phase::Warmup, 0, "warmup", warmup_condition, id);

    std::vector<std::string> practice = lists.practice;
    Rng practice_rng = subject_rng(design, subject, "practice");
    shuffle(practice, practice_rng);
    for (std::size_t i = 0; i < practice.size(); ++i) {
        const std::string condition =
            design.practice_condition.empty()
                ? protocol.conditions[static_cast<std::size_t>(order[i % order.size()])].name
                : design.practice_condition;
        add(Phase::Practice, 0, "practice", condition, practice[i]);
    }

    // The list paired with each condition for this subject.
    std::vector<int> list_of_condition(static_cast<std::size_t>(k));
    for (int l = 0; l < k; ++l) list_of_condition[static_cast<std::size_t>(paired_condition(l, subject, k))] = l;
    for (int b = 0; b < k; ++b) {
        const int c = order[static_cast<std::size_t>(b)];
        const int l = list_of_condition[static_cast<std::size_t>(c)];
        std::vector<std::string> sentences = lists.lists[static_cast<std::size_t>(l)];
        Rng rng = subject_rng(design, subject, fmt::format("block/{}", b + 1));
        shuffle(sentences, rng);
        for (const auto& id : sentences)
            add(Phase::Test, b + 1, std::to_string(l + 1), protocol.conditions[static_cast<std::size_t>(c)].name, id);
    }
    // Adaptive tracks interleaved: the blocks' sentences alternate one by one
    // in the block order (one test block, so no break between conditions).
    if (protocol.adaptive.present() &&
        analysis::adaptive_protocol(protocol).order == analysis::TrackOrder::Interleaved) {
        const auto first_test = std::find_if(trials.begin(), trials.end(), [](const PlannedTrial& t) {
            return t.phase == Phase::Test;
        });
        std::vector<std::vector<PlannedTrial>> blocks(static_cast<std::size_t>(k));
        for (auto it = first_test; it != trials.end(); ++it) blocks[static_cast<std::size_t>(it->block - 1)].push_back(*it);
        trials.erase(first_test, trials.end());
        for (std::size_t i = 0;; ++i) {
            bool any = false;
            for (const auto& block : blocks)
                if (i < block.size()) {
                    PlannedTrial t = block[i];
                    t.position = static_cast<int>(trials.size()) + 1;
                    t.block = 1;
                    trials.push_back(std::move(t));
                    any = true;
                }
            if (!any) break;
        }
    }
    return trials;
}

std::vector<PlannedTrial> make_design(const Protocol& protocol, const Corpus& corpus, int subjects) {
    if (subjects < 1) throw UsageError(fmt::format("--subjects: expected at least 1, got {}", subjects));
    const ListAssignment lists = assign_lists(corpus, protocol.design);
    std::vector<PlannedTrial> all;
    for (int s = 1; s <= subjects; ++s) {
        auto trials = design_subject(protocol, lists, s);
        all.insert(all.end(), trials.begin(), trials.end());
    }
    return all;
}

static const std::vector<std::string> lists_header = {"subject", "position", "phase",    "block",
                                                      "list",    "condition", "sentence", "stimulus"};

void write_lists_csv(const std::filesystem::path& path, const std::vector<PlannedTrial>& trials) {
    std::string text = csv_line(lists_header);
    for (const auto& t : trials)
        text += csv_line({std::to_string(t.subject), std::to_string(t.position), to_string(t.phase),
                          std::to_string(t.block), t.list, t.condition, t.sentence, t.stimulus});
    write_text_file(path, text);
}

std::vector<PlannedTrial> read_lists_csv(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    std::vector<std::size_t> col;
    for (const auto& name : lists_header) col.push_back(table.require_column(name));
    DiagnosticList problems;
    std::vector<PlannedTrial> trials;
    for (const auto& row : table.rows) {
        PlannedTrial t;
        auto integer = [&](std::size_t c, int& out) {
            const auto v = parse_int(row.fields[col[c]]);
            if (!v || *v < 0) {
                problems.add(table.path, row.line, 0, lists_header[c],
                             fmt::format("expected a non-negative integer, got \"{}\"", row.fields[col[c]]));
                return;
            }
            out = static_cast<int>(*v);
        };
        integer(0, t.subject);
        integer(1, t.position);
        if (!parse_phase(row.fields[col[2]], t.phase))
            problems.add(table.path, row.line, 0, "phase",
                         fmt::format("expected \"warmup\", \"practice\" or \"test\", got \"{}\"",
                                     row.fields[col[2]]));
        integer(3, t.block);
        t.list = row.fields[col[4]];
        t.condition = row.fields[col[5]];
        t.sentence = row.fields[col[6]];
        t.stimulus = row.fields[col[7]];
        trials.push_back(std::move(t));
    }
    problems.throw_if_any();
    return trials;
}

BalanceReport balance_report(const Protocol& protocol, const std::vector<PlannedTrial>& trials) {
    BalanceReport r;
    r.conditions = protocol.condition_names();
    const int k = static_cast<int>(r.conditions.size());
    for (int l = 1; l <= protocol.design.lists; ++l) r.lists.push_back(std::to_string(l));
    r.list_by_condition.assign(r.lists.size(), std::vector<int>(static_cast<std::size_t>(k), 0));
    r.condition_by_position.assign(static_cast<std::size_t>(k), std::vector<int>(static_cast<std::size_t>(k), 0));
    std::set<int> subjects;
    // Count each (subject, block) once for the block-level tables.
    std::set<std::pair<int, int>> seen_blocks;
    for (const auto& t : trials) {
        subjects.insert(t.subject);
        if (t.phase != Phase::Test) continue;
        const int c = protocol.condition_index(t.condition);
        const auto l = parse_int(t.list);
        if (c < 0 || !l || *l < 1 || *l > static_cast<long long>(r.lists.size()) || t.block < 1 || t.block > k) continue;
        if (!seen_blocks.insert({t.subject, t.block}).second) continue;
        ++r.list_by_condition[static_cast<std::size_t>(*l - 1)][static_cast<std::size_t>(c)];
        ++r.condition_by_position[static_cast<std::size_t>(c)][static_cast<std::size_t>(t.block - 1)];
    }
    r.subjects = static_cast<int>(subjects.size());
    return r;
}

std::string BalanceReport::text() const {
    std::size_t width = 9;
    for (const auto& c : conditions) width = std::max(width, c.size());
    std::string out = fmt::format("Balance over {} subjects (counts of test blocks).\n\n", subjects);
    out += "List × condition:\n";
    out += fmt::format("{:<6}", "list");
    for (const auto& c : conditions) out += fmt::format(" {:>{}}", c, width);
    out += "\n";
    for (std::size_t l = 0; l < lists.size(); ++l) {
        out += fmt::format("{:<6}", lists[l]);
        for (int n : list_by_condition[l]) out += fmt::format(" {:>{}}", n, width);
        out += "\n";
    }
    out += "\nCondition × block position:\n";
    out += fmt::format("{:<{}}", "condition", width);
    for (std::size_t p = 0; p < conditions.size(); ++p) out += fmt::format(" {:>5}", p + 1);
    out += "\n";
    for (std::size_t c = 0; c < conditions.size(); ++c) {
        out += fmt::format("{:<{}}", conditions[c], width);
        for (int n : condition_by_position[c]) out += fmt::format(" {:>5}", n);
        out += "\n";
    }
    return out;
}

}  // namespace avsi::experiment
