# gonio - top-level entry points. Each target installs what it needs
# (scripts/install-deps, idempotent), configures build/ and compiles.
BUILD      ?= build
ASAN_BUILD ?= build-asan
# the libFuzzer targets (tests/fuzz, docs/fuzzing.md): clang, -Dfuzzing=true
FUZZ_BUILD ?= build-fuzz
MESON_OPTS ?=
# Tests at once: most end-to-end tests wait on the simulated rig, so three keep 2 cores busy
# (those that compare rig time with wall time run alone: tests/e2e/meson.build).
TEST_JOBS  ?= 3

.PHONY: all deps build install demo test test-fast test-kernel test-asan test-fuzz bench format clean

all: build

deps:
	@scripts/install-deps

$(BUILD)/build.ninja:
	meson setup $(BUILD) $(MESON_OPTS)

$(ASAN_BUILD)/build.ninja:
	meson setup $(ASAN_BUILD) -Dbuildtype=debug -Doptimization=1 -Db_sanitize=address,undefined -Dbenchmarks=false $(MESON_OPTS)

$(FUZZ_BUILD)/build.ninja:
	CC=clang CXX=clang++ meson setup $(FUZZ_BUILD) -Dfuzzing=true -Dkernel_lane=false $(MESON_OPTS)

build: deps $(BUILD)/build.ninja
	ninja -C $(BUILD)

# Install the programs, man pages, bash completion, systemd units and docs (docs/install.md)
# under the prefix meson was configured with (MESON_OPTS=-Dprefix=/usr for a system, default
# /usr/local), below DESTDIR when given: make install DESTDIR=/tmp/stage
install: build
	meson install -C $(BUILD) --no-rebuild $(if $(DESTDIR),--destdir "$(DESTDIR)")

# Start gonio-sim and goniod on the simulated rig, capture a 4-DOF set with gonioctl.
demo: build
	scripts/demo $(BUILD)

# The whole suite, then once more under AddressSanitizer + UndefinedBehaviorSanitizer, then a
# few seconds of each fuzz target over its corpus. The kernel lane (qemu boots, run one at a
# time) runs once, in the sanitizer pass, where it also checks the backends' memory use;
# `make test-kernel` runs it alone in build/.
test: test-fast test-asan test-fuzz
	@scripts/test-summary $(BUILD) $(ASAN_BUILD) $(FUZZ_BUILD)

test-fast: build
	meson test -C $(BUILD) --print-errorlogs --num-processes $(TEST_JOBS) --no-suite kernel

test-kernel: build
	meson test -C $(BUILD) --print-errorlogs --suite kernel

test-asan: deps $(ASAN_BUILD)/build.ninja
	ninja -C $(ASAN_BUILD)
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
		meson test -C $(ASAN_BUILD) --print-errorlogs --timeout-multiplier 3 --num-processes $(TEST_JOBS)

# Builds only the fuzz targets and what they link (ninja's alias 'fuzz'), then runs suite 'fuzz'.
test-fuzz: deps $(FUZZ_BUILD)/build.ninja
	ninja -C $(FUZZ_BUILD) fuzz
	meson test -C $(FUZZ_BUILD) --no-rebuild --suite fuzz --print-errorlogs --num-processes 2

bench: build
	scripts/bench $(BUILD)

format:
	clang-format -i $$(git ls-files '*.c' '*.h' '*.cpp')

clean:
	rm -rf $(BUILD) $(ASAN_BUILD) $(FUZZ_BUILD)
