# The two commands: `make demo` (the main job) and `make test`. Each installs
# missing Debian packages, configures and builds incrementally, then runs.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
# ctest runs one more test than there are cores: several tests spend most of
# their time waiting (a browser's timers, the online sender's 2-minute outage,
# a Slurm job's queue), so a core would otherwise idle beside them.
TEST_JOBS ?= $(shell echo $$(( $(JOBS) + 1 )))
CMAKE_FLAGS ?=
# Unity builds (AVSI_UNITY_BUILD in CMakeLists.txt) for a faster first build;
# `make UNITY=OFF …` compiles file by file.
UNITY ?= ON
# Optimised without debug information (-O2 -DNDEBUG, the code RelWithDebInfo
# makes, minus -g): a shorter first build and link. `make BUILD_TYPE=RelWithDebInfo …`
# for a debuggable build.
BUILD_TYPE ?= Release
# Ninja for a new build folder when it is installed: it compiles the module
# libraries' sources in parallel instead of library after library. An
# existing folder keeps the generator it was configured with.
GENERATOR ?= $(if $(wildcard $(BUILD_DIR)/CMakeCache.txt),,$(if $(shell command -v ninja),-G Ninja,))
CONFIGURE = cmake -S . -B $(BUILD_DIR) $(GENERATOR) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) \
  -DCMAKE_CXX_FLAGS_RELEASE="-O2 -DNDEBUG" -DAVSI_UNITY_BUILD=$(UNITY) $(CMAKE_FLAGS)
ifneq ($(CI),)
CMAKE_FLAGS += -DAVSI_WERROR=ON
endif

.PHONY: all deps configure build build-cli test demo bench sanitize fuzz clean

all: build

deps:
	@scripts/install-deps

$(BUILD_DIR)/CMakeCache.txt: | deps
	$(CONFIGURE)

configure: deps
	$(CONFIGURE)

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

# The demo needs only the avsi executable, not the tests and benchmarks.
build-cli: configure
	cmake --build $(BUILD_DIR) -j $(JOBS) --target avsi

# Every test but the libFuzzer smoke (Fuzz.Smoke: a sanitizer build of the
# fuzz tree, about 10 minutes the first time), which belongs to `make fuzz`;
# `cd build && ctest -R Fuzz.Smoke` still runs it where clang is installed.
test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(TEST_JOBS) --timeout 900 -E '^Fuzz\.Smoke$$'

# PROTOCOL=FILE runs another protocol (out/demo-<name>), e.g.
# make demo PROTOCOL=protocols/beskow2004-sv.toml
demo: build-cli
	scripts/demo $(if $(PROTOCOL),--protocol $(PROTOCOL)) $(BUILD_DIR)

bench: build
	scripts/bench $(BUILD_DIR)

# An AddressSanitizer + UndefinedBehaviorSanitizer build and test run.
sanitize: deps
	cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DAVSI_SANITIZE=ON -DAVSI_BUILD_BENCH=OFF
	cmake --build build-asan -j $(JOBS)
	cd build-asan && ctest --output-on-failure -j $(JOBS) --label-exclude slow

# libFuzzer on every parser (clang; tests/fuzz/README.md): FUZZ_SECONDS per
# parser (default 5 minutes), new corpus entries kept in build-fuzz/corpus,
# findings in build-fuzz/findings, the summary table in build-fuzz/summary.md.
FUZZ_SECONDS ?= 300
fuzz: deps
	scripts/install-deps --fuzz
	scripts/fuzz --seconds $(FUZZ_SECONDS) --build-dir build-fuzz

clean:
	rm -rf $(BUILD_DIR) build-asan build-fuzz out
