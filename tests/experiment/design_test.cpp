#include "avsi/experiment/design.h"

#include <gtest/gtest.h>

#include <map>
#include <numeric>
#include <set>

#include "avsi/core/error.h"
#include "support/generated_study.h"
#include "support/temp_dir.h"

namespace avsi::experiment {
namespace {

using test::GeneratedStudy;
using test::temp_dir;
using test::write_study;

struct Loaded {
    Protocol protocol;
    Corpus corpus;
};

Loaded load(const std::string& name, const GeneratedStudy& g) {
    const auto path = write_study(temp_dir(name), g);
    Loaded l{load_protocol(path), {}};
    l.corpus = read_corpus(l.protocol.corpus.sentences);
    return l;
}

TEST(Design, EveryTestSentenceExactlyOncePerSubject) {
    const Loaded l = load("once", {});
    const auto trials = make_design(l.protocol, l.corpus, 12);
    std::set<std::string> test_ids;
    for (const auto& s : l.corpus.sentences)
        if (s.list != "warmup" && s.list != "practice") test_ids.insert(s.id);
    for (int subject = 1; subject <= 12; ++subject) {
        SCOPED_TRACE(subject);
        std::multiset<std::string> seen;
        int position = 0;
        Phase last = Phase::Warmup;
        for (const auto& t : trials) {
            if (t.subject != subject) continue;
            EXPECT_EQ(t.position, ++position);
            EXPECT_GE(static_cast<int>(t.phase), static_cast<int>(last));  // warm-up, practice, test
            last = t.phase;
            EXPECT_EQ(t.stimulus, t.sentence + "/" + t.condition + ".mp4");
            if (t.phase == Phase::Test) seen.insert(t.sentence);
        }
        EXPECT_EQ(position, 2 + 2 + 18);
        EXPECT_EQ(std::set<std::string>(seen.begin(), seen.end()), test_ids);
        EXPECT_EQ(seen.size(), test_ids.size());
    }
}

TEST(Design, EachListMeetsEachConditionEquallyOftenOverSixMSubjects) {
    const Loaded l = load("latin", {});
    for (int m = 1; m <= 3; ++m) {
        SCOPED_TRACE(m);
        const auto trials = make_design(l.protocol, l.corpus, 6 * m);
        const BalanceReport r = balance_report(l.protocol, trials);
        for (const auto& row : r.list_by_condition)
            for (int n : row) EXPECT_EQ(n, m);
        // Within a subject a block is one list in one condition.
        std::map<std::pair<int, int>, std::set<std::pair<std::string, std::string>>> blocks;
        for (const auto& t : trials)
            if (t.phase == Phase::Test) blocks[{t.subject, t.block}].insert({t.list, t.condition});
        for (const auto& [key, pairs] : blocks) EXPECT_EQ(pairs.size(), 1u);
    }
}

TEST(Design, RandomOrdersDifferAcrossSubjectsButRepeatWithTheSeed) {
    const Loaded l = load("seeded", {});
    const auto a = make_design(l.protocol, l.corpus, 6);
    const auto b = make_design(l.protocol, l.corpus, 6);
    EXPECT_EQ(a, b);
    std::set<std::vector<int>> orders;
    for (int s = 1; s <= 6; ++s) orders.insert(condition_order(l.protocol.design, 6, s));
    EXPECT_GT(orders.size(), 1u);
    GeneratedStudy other;
    other.seed = 12;
    const Loaded l2 = load("seeded2", other);
    EXPECT_NE(make_design(l2.protocol, l2.corpus, 6), a);
}

TEST(Design, WilliamsRowsAreBalancedForPositionAndCarryOver) {
    for (int k = 2; k <= 9; ++k) {
        SCOPED_TRACE(k);
        const auto rows = williams_design(k);
        ASSERT_EQ(static_cast<int>(rows.size()), k % 2 ? 2 * k : k);
        std::map<std::pair<int, int>, int> at_position, pairs;
        for (const auto& row : rows) {
            ASSERT_EQ(std::set<int>(row.begin(), row.end()).size(), static_cast<std::size_t>(k));
            for (int p = 0; p < k; ++p) ++at_position[{row[p], p}];
            for (int p = 0; p + 1 < k; ++p) ++pairs[{row[p], row[p + 1]}];
        }
        const int per_position = static_cast<int>(rows.size()) / k;
        for (int c = 0; c < k; ++c)
            for (int p = 0; p < k; ++p) EXPECT_EQ((at_position[{c, p}]), per_position);
        const int per_pair = static_cast<int>(rows.size()) * (k - 1) / (k * (k - 1));
        EXPECT_EQ(pairs.size(), static_cast<std::size_t>(k * (k - 1)));
        for (const auto& [pair, n] : pairs) EXPECT_EQ(n, per_pair);
    }
}

TEST(Design, WilliamsOptionBalancesSubjectsPositionsAndNeighbours) {
    for (int k : {4, 5, 6}) {
        SCOPED_TRACE(k);
        GeneratedStudy g;
        g.conditions = k;
        g.per_list = 2;
        g.counterbalance = "williams";
        const Loaded l = load("williams" + std::to_string(k), g);
        const int rows = k % 2 ? 2 * k : k;
        // A multiple of both the square's rows and k, so lists balance too.
        const int subjects = std::lcm(rows, k) * 2;
        const auto trials = make_design(l.protocol, l.corpus, subjects);
        const BalanceReport r = balance_report(l.protocol, trials);
        for (const auto& row : r.condition_by_position)
            for (int n : row) EXPECT_EQ(n, subjects / k);
        for (const auto& row : r.list_by_condition)
            for (int n : row) EXPECT_EQ(n, subjects / k);
        std::map<std::pair<std::string, std::string>, int> neighbours;
        std::map<int, std::vector<std::string>> order;
        for (const auto& t : trials)
            if (t.phase == Phase::Test && (order[t.subject].empty() || order[t.subject].back() != t.condition))
                order[t.subject].push_back(t.condition);
        for (const auto& [s, o] : order) {
            ASSERT_EQ(static_cast<int>(o.size()), k);
            for (int p = 0; p + 1 < k; ++p) ++neighbours[{o[p], o[p + 1]}];
        }
        EXPECT_EQ(neighbours.size(), static_cast<std::size_t>(k * (k - 1)));
        for (const auto& [pair, n] : neighbours) EXPECT_EQ(n, subjects / k);
    }
}

TEST(Design, WithoutAListColumnListsAreSeededEqualAndDisjoint) {
    GeneratedStudy g;
    g.list_column = false;
    g.extra_sentences = 3;
    const Loaded l = load("nolists", g);
    const ListAssignment a = assign_lists(l.corpus, l.protocol.design);
    const ListAssignment b = assign_lists(l.corpus, l.protocol.design);
    EXPECT_EQ(a.lists, b.lists);
    std::set<std::string> all;
    EXPECT_EQ(a.warmup.size(), 2u);
    EXPECT_EQ(a.practice.size(), 2u);
    all.insert(a.warmup.begin(), a.warmup.end());
    all.insert(a.practice.begin(), a.practice.end());
    for (const auto& list : a.lists) {
        EXPECT_EQ(list.size(), 3u);
        all.insert(list.begin(), list.end());
    }
    EXPECT_EQ(all.size(), 2u + 2u + 18u);
}

TEST(Design, CorpusThatDoesNotFitTheDesignIsAnInputError) {
    GeneratedStudy g;
    const auto dir = temp_dir("misfit");
    write_study(dir, g);
    // Claim 4 sentences per list where the corpus has 3.
    std::string text = read_text_file(dir / "protocol.toml");
    text.replace(text.find("sentences_per_list = 3"), 22, "sentences_per_list = 4");
    write_text_file(dir / "protocol.toml", text);
    const Protocol p = load_protocol(dir / "protocol.toml");
    try {
        assign_lists(read_corpus(p.corpus.sentences), p.design);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.diagnostics().size(), 6u);
        EXPECT_NE(std::string(e.what()).find("list 1 has 3 sentences"), std::string::npos);
    }
}

TEST(Design, ListsCsvRoundTrips) {
    const Loaded l = load("csv", {});
    const auto trials = make_design(l.protocol, l.corpus, 3);
    const auto path = temp_dir("csv_out") / "lists.csv";
    write_lists_csv(path, trials);
    EXPECT_EQ(read_lists_csv(path), trials);
    EXPECT_EQ(read_text_file(path).substr(0, 62), "subject,position,phase,block,list,condition,sentence,stimulus\n");
}

TEST(Design, BalanceReportTextShowsBothTables) {
    const Loaded l = load("report", {});
    const std::string text = balance_report(l.protocol, make_design(l.protocol, l.corpus, 6)).text();
    EXPECT_NE(text.find("List × condition"), std::string::npos);
    EXPECT_NE(text.find("Condition × block position"), std::string::npos);
    EXPECT_NE(text.find("over 6 subjects"), std::string::npos);
}

}  // namespace
}  // namespace avsi::experiment
