# cogw — top-level build. `make` builds everything; `make test` runs the whole suite
# (unit tests natively, integration tests on vcan lines, in a VM where needed);
# `make demo` runs the gateway demo; `make deps` installs what all of this needs.
#
# Two configurations live side by side:
#   build/rel  -O2, what `make`, `make install` and `make bench` use;
#   build/san  ASan+UBSan, what the tests use.

PREFIX  ?= /usr/local
DESTDIR ?=
CC      ?= gcc
ifeq ($(origin CC),default)
CC      := gcc
endif

UNITY_SRC ?= .deps/unity/src

WARN    := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes
BASE    := -std=gnu11 $(WARN) -I. -D_GNU_SOURCE -MMD -MP
REL_CFLAGS := $(BASE) -O2 -g
SAN_CFLAGS := $(BASE) -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
SAN_LDFLAGS := -fsanitize=address,undefined
UNITY_CFLAGS := -I$(UNITY_SRC) -DUNITY_INCLUDE_DOUBLE -DUNITY_SUPPORT_64 -DUNITY_USE_FLUSH_STDOUT

CORE_SRC    := $(sort $(wildcard core/*.c))
LINES_SRC   := $(sort $(wildcard lines/*.c))
UNIT_SRC    := $(sort $(wildcard tests/unit/test_*.c))
UNIT_SUP    := $(sort $(wildcard tests/unit/support/*.c))
INTEG_SRC   := $(sort $(wildcard tests/integration/test_*.c))
INTEG_SUP   := $(sort $(wildcard tests/integration/support/*.c))
BENCH_SRC   := $(sort $(wildcard tests/bench/bench_*.c))

REL := build/rel
SAN := build/san

obj = $(patsubst %.c,$(1)/obj/%.o,$(2))

REL_CORE_LIB := $(REL)/lib/libcogw_core.a
SAN_CORE_LIB := $(SAN)/lib/libcogw_core.a
REL_LINES_LIB := $(REL)/lib/libcogw_lines.a
SAN_LINES_LIB := $(SAN)/lib/libcogw_lines.a

UNIT_BINS  := $(patsubst tests/unit/%.c,$(SAN)/tests/unit/%,$(UNIT_SRC))
INTEG_BINS := $(patsubst tests/integration/%.c,$(SAN)/tests/integration/%,$(INTEG_SRC))
BENCH_BINS := $(patsubst tests/bench/%.c,$(REL)/tests/bench/%,$(BENCH_SRC))

.PHONY: all deps test unit integration bench demo install clean tests-build check-core-io
.DEFAULT_GOAL := all
.SECONDARY:

all: $(REL_CORE_LIB) $(REL_LINES_LIB)

# ---- compilation ---------------------------------------------------------------
$(REL)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(REL_CFLAGS) -c $< -o $@

$(SAN)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(SAN_CFLAGS) -c $< -o $@

# Unity is third-party code: compiled with its own relaxed warnings, never committed.
$(SAN)/obj/unity.o: $(UNITY_SRC)/unity.c
	@mkdir -p $(@D)
	$(CC) -std=gnu11 -O1 -g $(UNITY_CFLAGS) -fsanitize=address,undefined -c $< -o $@

$(SAN)/obj/tests/%.o: tests/%.c
	@mkdir -p $(@D)
	$(CC) $(SAN_CFLAGS) $(UNITY_CFLAGS) -c $< -o $@

$(UNITY_SRC)/unity.c:
	@echo "Unity sources missing in $(UNITY_SRC): run 'make deps' (or set UNITY_DIR)"; exit 1

# ---- libraries -----------------------------------------------------------------
$(REL_CORE_LIB): $(call obj,$(REL),$(CORE_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_CORE_LIB): $(call obj,$(SAN),$(CORE_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(REL_LINES_LIB): $(call obj,$(REL),$(LINES_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_LINES_LIB): $(call obj,$(SAN),$(LINES_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# ---- tests ---------------------------------------------------------------------
$(SAN)/tests/unit/%: $(SAN)/obj/tests/unit/%.o $(call obj,$(SAN),$(UNIT_SUP)) $(SAN)/obj/unity.o $(SAN_LINES_LIB) $(SAN_CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(SAN_LDFLAGS) -o $@ $^ -lm

$(SAN)/tests/integration/%: $(SAN)/obj/tests/integration/%.o $(call obj,$(SAN),$(INTEG_SUP)) $(SAN)/obj/unity.o $(SAN_LINES_LIB) $(SAN_CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(SAN_LDFLAGS) -o $@ $^ -lrt -lpthread -lm

tests-build: $(UNIT_BINS) $(INTEG_BINS)

unit: $(UNIT_BINS)
	tests/run-tests unit $(UNIT_BINS)

integration: $(INTEG_BINS)
	tests/vcan/run -n 3 -- tests/run-tests integration $(INTEG_BINS)

# The whole suite: set-up if needed, build, unit tests, then integration tests on
# 3 vcan lines; one closing line "N passed, M failed".
test:
	@scripts/deps.sh
	@$(MAKE) --no-print-directory all tests-build
	@tests/run-all "$(UNIT_BINS)" "$(INTEG_BINS)"

# ---- benchmarks ----------------------------------------------------------------
$(REL)/tests/bench/%: $(REL)/obj/tests/bench/%.o $(REL_CORE_LIB)
	@mkdir -p $(@D)
	$(CC) -o $@ $^ -lm

bench: $(BENCH_BINS)
	@for b in $(BENCH_BINS); do echo "== $$b"; $$b || exit 1; done

# ---- demo ----------------------------------------------------------------------
demo:
	@scripts/deps.sh
	@$(MAKE) --no-print-directory all
	tests/vcan/run -n 3 -- scripts/demo.sh

# ---- install -------------------------------------------------------------------
install: all
	install -d $(DESTDIR)$(PREFIX)/lib $(DESTDIR)$(PREFIX)/include/cogw/core
	install -m 644 $(REL_CORE_LIB) $(DESTDIR)$(PREFIX)/lib/
	install -m 644 core/*.h $(DESTDIR)$(PREFIX)/include/cogw/core/

deps:
	scripts/deps.sh

clean:
	rm -rf build

-include $(shell find build -name '*.d' 2>/dev/null)
