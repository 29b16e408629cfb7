// Options whose value is one of a fixed set of names (--spacing greenwood,
// --audio null, --camera front): one rule for every command, so each fails
// the same way, when the line is parsed and before any work, with exit
// status 2 and the allowed values:
//   avsi vocode: --spacing: expected one of greenwood, log, linear, got "lin" (did you mean "linear"?)
// Header-only (CLI11 and core's closest_match.h).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "avsi/core/closest_match.h"

namespace avsi::cli {

// A CLI11 check that the value is one of `names`; help shows them as
// {a,b,c}. Use it on every option that takes one of a fixed set of names:
//   sub.add_option("--spacing", o->spacing, "Band spacing")->check(one_of({"greenwood", "log", "linear"}));
inline CLI::Validator one_of(std::vector<std::string> names) {
    std::string shown;
    for (const std::string& n : names) shown += (shown.empty() ? "" : ",") + n;
    return CLI::Validator(
        [names](std::string& value) -> std::string {
            for (const std::string& n : names)
                if (value == n) return {};
            std::string listed;
            for (const std::string& n : names) listed += (listed.empty() ? "" : ", ") + n;
            const std::string hint = closest_match(value, names);
            return "expected one of " + listed + ", got \"" + value + "\"" +
                   (hint.empty() ? "" : " (did you mean \"" + hint + "\"?)");
        },
        "{" + shown + "}", "one of");
}

}  // namespace avsi::cli
