// The report's "Stimuli and audio processing" section (methods_report.h):
// the stimulus set's methods from its manifest, in report.md and index.html,
// and the checks that the scores and the set belong together.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "avsi/analysis/methods_report.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using namespace avsi;

const char* const k_methods =
    "# Methods: the stimuli of study\n\n"
    "2 sentences were synthesised with espeak:en; each stimulus's speech was set to -23 dBFS.\n\n"
    "Conditions:\n\n"
    "- audio-only: no face, vocoded audio.\n"
    "- rule: control model rule.json (as trained), vocoded audio.\n\n"
    "Audio of the vocoded conditions:\n\n"
    "- Carrier: rectangular pulse train, 250 pulses/s in every band <interleaved> & timed\n"
    "- Channel selection: 4-of-8 per 2.5 ms frame\n";

struct MethodsFixture : ::testing::Test {
    fs::path dir = avsi::test::temp_dir("methods_report");
    fs::path report = dir / "report", stimuli = dir / "stimuli";
    void SetUp() override {
        fs::create_directories(report);
        fs::create_directories(stimuli);
        write_text_file(report / "report.md", "# Report\n");
        write_text_file(report / "index.html", "<html><body><h1>Report</h1>\n</body></html>\n");
    }
    void write_manifest(bool with_methods) {
        nlohmann::json m = {{"format", "avsi-stimuli-manifest"},
                            {"conditions", {{{"name", "audio-only"}}, {{"name", "rule"}}}}};
        if (with_methods) m["methods"] = k_methods;
        write_text_file(stimuli / "manifest.json", m.dump(2));
    }
};

TEST_F(MethodsFixture, TheManifestsMethodsGoIntoBothReports) {
    write_manifest(true);
    analysis::append_methods_section(report, stimuli, {"audio-only", "rule"});
    const std::string md = read_text_file(report / "report.md");
    EXPECT_EQ(md.rfind("# Report\n", 0), 0u) << md;
    EXPECT_NE(md.find("\n## Stimuli and audio processing\n"), std::string::npos) << md;
    EXPECT_NE(md.find("- Channel selection: 4-of-8 per 2.5 ms frame\n"), std::string::npos) << md;
    EXPECT_EQ(md.find("# Methods: the stimuli of study"), std::string::npos) << "the set's own title is dropped";
    const std::string html = read_text_file(report / "index.html");
    const auto section = html.find("<h2>Stimuli and audio processing</h2>");
    ASSERT_NE(section, std::string::npos) << html;
    EXPECT_LT(section, html.find("</body>"));
    EXPECT_NE(html.find("<li>Carrier: rectangular pulse train, 250 pulses/s in every band &lt;interleaved&gt; "
                        "&amp; timed</li>"),
              std::string::npos)
        << html;
    EXPECT_NE(html.find("<p>2 sentences were synthesised with espeak:en; each stimulus's speech"),
              std::string::npos)
        << html;
}

TEST_F(MethodsFixture, AnOlderSetsMethodsMdIsRead) {
    write_manifest(false);
    write_text_file(stimuli / "methods.md", k_methods);
    analysis::append_methods_section(report, stimuli, {"rule"});
    EXPECT_NE(read_text_file(report / "report.md").find("Channel selection: 4-of-8"), std::string::npos);
}

TEST_F(MethodsFixture, ScoresOfConditionsTheSetLacksAreRefused) {
    write_manifest(true);
    try {
        analysis::append_methods_section(report, stimuli, {"rule", "ohman", "ann1"});
        FAIL() << "accepted conditions the set lacks";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("manifest.json"), std::string::npos) << what;
        EXPECT_NE(what.find("conditions ohman, ann1 are not in this stimulus set (it has audio-only, rule)"),
                  std::string::npos)
            << what;
    }
    EXPECT_EQ(read_text_file(report / "report.md"), "# Report\n") << "nothing is written on a refusal";
}

TEST_F(MethodsFixture, AFolderWithoutAManifestIsRefused) {
    try {
        analysis::append_methods_section(report, dir / "nothing", {"rule"});
        FAIL() << "accepted a folder without a manifest";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("no manifest.json in this folder"), std::string::npos) << e.what();
    }
    write_manifest(false);
    try {
        analysis::append_methods_section(report, stimuli, {"rule"});
        FAIL() << "accepted a manifest without methods";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("no \"methods\" in the manifest"), std::string::npos) << e.what();
    }
}

TEST(MethodsMarkdownHtml, HeadingsListsAndParagraphs) {
    EXPECT_EQ(analysis::methods_markdown_html("# A & B\n\nline one\nline two\n\n- x < y\n- z\n\nend\n"),
              "<h3>A &amp; B</h3>\n<p>line one line two</p>\n<ul>\n<li>x &lt; y</li>\n<li>z</li>\n</ul>\n<p>end</p>\n");
}

}  // namespace
