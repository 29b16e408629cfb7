// The built-in head for tests that draw, measure or animate it, loaded once
// per process.
#pragma once

#include "avsi/stimuli/head.h"

namespace avsi::test {

inline const stimuli::Head& default_head() {
    static const stimuli::Head head = stimuli::load_default_head();
    return head;
}

}  // namespace avsi::test
