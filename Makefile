# cogw — top-level build. `make` builds everything; `make test` runs the whole suite
# (unit tests natively, integration tests on vcan lines, in a VM where needed);
# `make demo` runs the gateway demo; `make deps` installs what all of this needs.
#
# Two configurations live side by side:
#   build/rel  -O2, what `make`, `make install` and `make bench` use;
#   build/san  ASan+UBSan, what the tests use;
# and a third for what threads share:
#   build/tsan ThreadSanitizer, the multi-threaded stress tests in tests/tsan/.

# ---- what a packager sets (GNU make conventions; docs/install.md) -------------
# CC, AR, PKG_CONFIG, CFLAGS, CPPFLAGS, LDFLAGS come from the command line or the
# environment; the flags the sources need (-std, -I., -D_GNU_SOURCE) are added
# before them, so a packager's CFLAGS replace only the optimisation and debug flags.
# WERROR: -Werror in a git checkout (developers, CI), nothing in a release tarball,
# so that the next compiler's new warnings do not break a distribution's build;
# `make WERROR=` or `make WERROR=-Werror` decide either way.
VERSION := $(shell cat VERSION)
PREFIX  ?= /usr/local
DESTDIR ?=
CC      ?= gcc
ifeq ($(origin CC),default)
CC      := gcc
endif
ifeq ($(origin AR),default)
AR      := ar
endif
PKG_CONFIG ?= pkg-config
CFLAGS   ?= -O2 -g
CPPFLAGS ?=
LDFLAGS  ?=
WERROR   ?= $(if $(wildcard .git),-Werror)

# GNU directory variables, under PREFIX unless set; the configuration stays in
# /etc (where the units look for it) unless SYSCONFDIR/sysconfdir say otherwise.
prefix        ?= $(PREFIX)
exec_prefix   ?= $(prefix)
bindir        ?= $(exec_prefix)/bin
libdir        ?= $(exec_prefix)/lib
includedir    ?= $(prefix)/include
datarootdir   ?= $(prefix)/share
docdir        ?= $(datarootdir)/doc/cogw
mandir        ?= $(datarootdir)/man
SYSCONFDIR    ?= /etc
sysconfdir    ?= $(SYSCONFDIR)
UNITDIR       ?= $(prefix)/lib/systemd/system
pkgconfigdir  ?= $(libdir)/pkgconfig

UNITY_SRC ?= .deps/unity/src

WARN    := -Wall -Wextra $(WERROR) -Wshadow -Wstrict-prototypes
# 64-bit file offsets, inode numbers and time_t on 32-bit targets too (armhf):
# readdir() of a large file system, and the TIME producer's clock after 2038
# (no effect where they are 64-bit already; no such type in the public headers).
BASE    := -std=gnu11 $(WARN) -I. -D_GNU_SOURCE -D_FILE_OFFSET_BITS=64 -D_TIME_BITS=64 -MMD -MP
REL_CFLAGS := $(BASE) $(CPPFLAGS) $(CFLAGS)
SAN_CFLAGS := $(BASE) -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
SAN_LDFLAGS := -fsanitize=address,undefined
UNITY_CFLAGS := -I$(UNITY_SRC) -DUNITY_INCLUDE_DOUBLE -DUNITY_SUPPORT_64 -DUNITY_USE_FLUSH_STDOUT

CORE_SRC    := $(sort $(wildcard core/*.c))
LINES_SRC   := $(sort $(wildcard lines/*.c))
GATEWAY_SRC := $(sort $(wildcard gateway/*.c))
MANAGER_SRC := $(sort $(wildcard manager/*.c))
DEVOBJ_SRC  := $(sort $(wildcard devobj/*.c))
APPCOMMON_SRC := $(sort $(wildcard apps/common/*.c))
# Generated at build time, never committed: etc/cogw.json as a C string.
GEN := build/gen
APPCOMMON_GEN := $(GEN)/default_config.c $(GEN)/default_files.c $(GEN)/version.c
# files the embedded default configuration names (node configurations)
DEFAULT_FILES := $(sort $(wildcard etc/*.dcf))
PROGRAMS    := $(notdir $(patsubst %/main.c,%,$(wildcard apps/*/main.c)))
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
REL_GATEWAY_LIB := $(REL)/lib/libcogw_gateway.a
SAN_GATEWAY_LIB := $(SAN)/lib/libcogw_gateway.a
REL_MANAGER_LIB := $(REL)/lib/libcogw_manager.a
SAN_MANAGER_LIB := $(SAN)/lib/libcogw_manager.a
REL_DEVOBJ_LIB := $(REL)/lib/libcogw_devobj.a
SAN_DEVOBJ_LIB := $(SAN)/lib/libcogw_devobj.a
REL_APPCOMMON_LIB := $(REL)/lib/libcogw_appcommon.a
SAN_APPCOMMON_LIB := $(SAN)/lib/libcogw_appcommon.a
# Libraries every program and test links, most dependent first.
# (mailbox libraries are added to these lists where they are defined below)
# mailbox: libcogw_mbxsrv.a (daemon side, proto*.c + server*.c + budget.c) and
# libcogw.a/.so (client library, proto*.c + client*.c); rules at the end of this file.
MBX_PROTO_SRC  := $(sort $(wildcard mailbox/proto*.c))
MBX_SERVER_SRC := $(MBX_PROTO_SRC) $(sort $(wildcard mailbox/server*.c)) mailbox/budget.c
MBX_CLIENT_SRC := $(MBX_PROTO_SRC) $(sort $(wildcard mailbox/client*.c))
REL_MBXSRV_LIB := $(REL)/lib/libcogw_mbxsrv.a
SAN_MBXSRV_LIB := $(SAN)/lib/libcogw_mbxsrv.a
REL_COGW_LIB := $(REL)/lib/libcogw.a
SAN_COGW_LIB := $(SAN)/lib/libcogw.a
REL_COGW_SO := $(REL)/lib/libcogw.so
REL_LIBS = $(REL_APPCOMMON_LIB) $(REL_DEVOBJ_LIB) $(REL_MANAGER_LIB) $(REL_GATEWAY_LIB) $(REL_LINES_LIB) $(REL_MBXSRV_LIB) $(REL_COGW_LIB) $(REL_CORE_LIB)
SAN_LIBS = $(SAN_APPCOMMON_LIB) $(SAN_DEVOBJ_LIB) $(SAN_MANAGER_LIB) $(SAN_GATEWAY_LIB) $(SAN_LINES_LIB) $(SAN_MBXSRV_LIB) $(SAN_COGW_LIB) $(SAN_CORE_LIB)
SYS_LIBS := $(shell $(PKG_CONFIG) --libs libcjson libsystemd 2>/dev/null || echo -lcjson -lsystemd) -lrt -lpthread -lm
PROGRAM_BINS := $(addprefix $(REL)/bin/,$(PROGRAMS))
SAN_PROGRAM_BINS := $(addprefix $(SAN)/bin/,$(PROGRAMS))

UNIT_BINS  := $(patsubst tests/unit/%.c,$(SAN)/tests/unit/%,$(UNIT_SRC))
INTEG_BINS := $(patsubst tests/integration/%.c,$(SAN)/tests/integration/%,$(INTEG_SRC))
# ThreadSanitizer: tests/tsan/test_*.c, linked with the modules threads share
# (TSAN_LIB_SRC) and core/ as an archive (only what they call is pulled in),
# all compiled with -fsanitize=thread.
TSAN := build/tsan
TSAN_CFLAGS := $(BASE) -O1 -g -fno-omit-frame-pointer -fsanitize=thread
# Those that run real line threads on vcan (tests/tsan/vcan_*.c) run in the VM,
# with the integration tests.
TSAN_SRC := $(sort $(wildcard tests/tsan/test_*.c))
TSAN_VCAN_SRC := $(sort $(wildcard tests/tsan/vcan_*.c))
TSAN_LIB_SRC := $(LINES_SRC) $(GATEWAY_SRC) $(sort $(MBX_CLIENT_SRC) $(MBX_SERVER_SRC))
TSAN_CORE_LIB := $(TSAN)/lib/libcogw-core.a
TSAN_BINS := $(patsubst tests/tsan/%.c,$(TSAN)/tests/tsan/%,$(TSAN_SRC))
TSAN_VCAN_BINS := $(patsubst tests/tsan/%.c,$(TSAN)/tests/tsan/%,$(TSAN_VCAN_SRC))
BENCH_BINS := $(patsubst tests/bench/%.c,$(REL)/tests/bench/%,$(BENCH_SRC))

.PHONY: all deps test cross cross-test cross-check-arch deb unit tsan integration interop bench bench-costs bench-timeline demo install clean tests-build check check-core-io check-layering format check-callgraph
.DEFAULT_GOAL := all
.SECONDARY:

all: $(REL_LIBS) $(PROGRAM_BINS)

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
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_CORE_LIB): $(call obj,$(SAN),$(CORE_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(REL_LINES_LIB): $(call obj,$(REL),$(LINES_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_LINES_LIB): $(call obj,$(SAN),$(LINES_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(REL_GATEWAY_LIB): $(call obj,$(REL),$(GATEWAY_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_GATEWAY_LIB): $(call obj,$(SAN),$(GATEWAY_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(REL_MANAGER_LIB): $(call obj,$(REL),$(MANAGER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_MANAGER_LIB): $(call obj,$(SAN),$(MANAGER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(REL_DEVOBJ_LIB): $(call obj,$(REL),$(DEVOBJ_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_DEVOBJ_LIB): $(call obj,$(SAN),$(DEVOBJ_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

# The ASCII gateway's parser, value texts and configuration loader: linked into the unit
# tests and the fuzz targets as well as into apps/cogw-ascii.
ASCII_LIB_SRC := apps/cogw-ascii/ascii_parse.c apps/cogw-ascii/ascii_value.c apps/cogw-ascii/ascii_config.c
SAN_ASCII_LIB := $(SAN)/lib/libcogw_ascii.a
$(SAN_ASCII_LIB): $(call obj,$(SAN),$(ASCII_LIB_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

# The MQTT bridge's request decoder and configuration loader: linked into the unit
# tests and the fuzz targets as well as into apps/cogw-mqtt (no libmosquitto in them).
MQTT_LIB_SRC := apps/cogw-mqtt/mqtt_request.c apps/cogw-mqtt/mqtt_config.c
SAN_MQTT_LIB := $(SAN)/lib/libcogw_mqtt.a
$(SAN_MQTT_LIB): $(call obj,$(SAN),$(MQTT_LIB_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(REL_APPCOMMON_LIB): $(call obj,$(REL),$(APPCOMMON_SRC) $(APPCOMMON_GEN))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_APPCOMMON_LIB): $(call obj,$(SAN),$(APPCOMMON_SRC) $(APPCOMMON_GEN))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

# ---- programs: apps/<name>/*.c -> build/<cfg>/bin/<name> -----------------------
# The sanitizer build of the programs is what the integration tests run.
# PROGRAM_SRC_<name>: sources of other directories a program links too;
# PROGRAM_LIBS_<name>: system libraries only it needs.
PROGRAM_SRC_cogw-mqtt := apps/cogw-ascii/ascii_value.c
PROGRAM_LIBS_cogw-mqtt := $(shell $(PKG_CONFIG) --libs libmosquitto 2>/dev/null || echo -lmosquitto)
define program_rules
$(REL)/bin/$(1): $(call obj,$(REL),$(wildcard apps/$(1)/*.c) $(PROGRAM_SRC_$(1))) $$(REL_LIBS)
	@mkdir -p $$(@D)
	$$(CC) $$(CFLAGS) $$(LDFLAGS) -o $$@ $$^ $$(PROGRAM_LIBS_$(1)) $$(SYS_LIBS)
$(SAN)/bin/$(1): $(call obj,$(SAN),$(wildcard apps/$(1)/*.c) $(PROGRAM_SRC_$(1))) $$(SAN_LIBS)
	@mkdir -p $$(@D)
	$$(CC) $$(SAN_LDFLAGS) -o $$@ $$^ $$(PROGRAM_LIBS_$(1)) $$(SYS_LIBS)
endef
$(foreach p,$(PROGRAMS),$(eval $(call program_rules,$(p))))

# ---- tests ---------------------------------------------------------------------
$(SAN)/tests/unit/%: $(SAN)/obj/tests/unit/%.o $(call obj,$(SAN),$(UNIT_SUP)) $(SAN)/obj/unity.o $(SAN_MQTT_LIB) $(SAN_ASCII_LIB) $(SAN_LIBS)
	@mkdir -p $(@D)
	$(CC) $(SAN_LDFLAGS) -o $@ $^ $(SYS_LIBS)

# cogwctl's value texts (its --json values) are checked without the program.
$(SAN)/tests/unit/test_real_text: $(SAN)/obj/tests/unit/test_real_text.o $(SAN)/obj/apps/cogwctl/util.o $(call obj,$(SAN),$(UNIT_SUP)) $(SAN)/obj/unity.o $(SAN_MQTT_LIB) $(SAN_ASCII_LIB) $(SAN_LIBS)
	@mkdir -p $(@D)
	$(CC) $(SAN_LDFLAGS) -o $@ $^ $(SYS_LIBS)

$(SAN)/tests/integration/%: $(SAN)/obj/tests/integration/%.o $(call obj,$(SAN),$(INTEG_SUP)) $(SAN)/obj/unity.o $(SAN_ASCII_LIB) $(SAN_LIBS)
	@mkdir -p $(@D)
	$(CC) $(SAN_LDFLAGS) -o $@ $^ $(SYS_LIBS)

tests-build: $(UNIT_BINS) $(INTEG_BINS) $(SAN_PROGRAM_BINS) $(TSAN_BINS) $(TSAN_VCAN_BINS)

# ---- ThreadSanitizer build ---------------------------------------------------------
$(TSAN)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(TSAN_CFLAGS) -c $< -o $@

$(TSAN)/obj/tests/%.o: tests/%.c
	@mkdir -p $(@D)
	$(CC) $(TSAN_CFLAGS) $(UNITY_CFLAGS) -c $< -o $@

$(TSAN)/obj/unity.o: $(UNITY_SRC)/unity.c
	@mkdir -p $(@D)
	$(CC) -std=gnu11 -O1 -g $(UNITY_CFLAGS) -fsanitize=thread -c $< -o $@

$(TSAN_CORE_LIB): $(call obj,$(TSAN),$(CORE_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(TSAN)/tests/tsan/%: $(TSAN)/obj/tests/tsan/%.o $(call obj,$(TSAN),$(TSAN_LIB_SRC)) $(TSAN)/obj/unity.o $(TSAN_CORE_LIB)
	@mkdir -p $(@D)
	$(CC) -fsanitize=thread -o $@ $^ -lrt -lpthread

tsan: $(TSAN_BINS)
	tests/run-tests tsan $(TSAN_BINS)

unit: $(UNIT_BINS)
	tests/run-tests unit $(UNIT_BINS)

integration: $(INTEG_BINS) $(TSAN_VCAN_BINS)
	tests/vcan/run -n 3 -- tests/run-tests integration $(INTEG_BINS) $(TSAN_VCAN_BINS)

# No call cycle between the files of core/, lines/, mailbox/, gateway/, manager/ or devobj/, nor between the files of
# one folder of apps/ (scripts/callgraph-cycles: who calls whose functions, from the object files' symbols).
check-callgraph:
	scripts/callgraph-cycles core lines mailbox gateway manager devobj
	for d in apps/*/; do scripts/callgraph-cycles $${d%/} || exit 1; done

# Interoperability with python-canopen (tests/interop/): one VM boot for the group.
# scripts/pyenv.sh installs the pinned packages into build/pyenv on first use.
# tests/interop/run-mqtt: the MQTT bridge against mosquitto and paho-mqtt, in the same boot.
INTEROP_TESTS := tests/interop/run tests/interop/run-mqtt tests/interop/run-network
interop: $(SAN_PROGRAM_BINS)
	@scripts/pyenv.sh
	tests/vcan/run -n 3 -- env COGW_TEST_TIMEOUT=$${COGW_INTEROP_TIMEOUT:-1800} tests/run-tests interop $(INTEROP_TESTS)

# The Python package's own tests (python/tests, pytest; docs/python.md "Tests"):
# against cogwd on 3 vcan lines, with the release libcogw.so; one VM boot.
PYTHON_TESTS := tests/python/run
.PHONY: python-test
python-test: all $(SAN_PROGRAM_BINS)
	@scripts/pyenv.sh
	tests/vcan/run -n 3 -- tests/run-tests python $(PYTHON_TESTS)

# The MQTT group alone (one VM boot).
.PHONY: interop-mqtt
interop-mqtt: $(SAN_PROGRAM_BINS)
	@scripts/pyenv.sh
	tests/vcan/run -n 3 -- tests/run-tests mqtt tests/interop/run-mqtt

# The whole suite: set-up if needed, build, unit tests, then integration tests on
# 3 vcan lines, the interoperability group and the Python package's tests in the
# same VM boot; one closing line "N passed, M failed".
test:
	@scripts/deps.sh
	@scripts/pyenv.sh
	@$(MAKE) --no-print-directory all tests-build
	@tests/run-all "$(UNIT_BINS)" "$(INTEG_BINS) $(TSAN_VCAN_BINS)" "$(TSAN_BINS)" "$(INTEROP_TESTS)" "$(PYTHON_TESTS)"

# ---- house rules -----------------------------------------------------------------
# `make check` runs every tests/checks/check_* script (layering, core I/O, format, ...);
# `make test` runs them first. `make format` applies .clang-format to the tree.
check:
	tests/checks/run

check-core-io:
	scripts/check-core-io

check-layering:
	scripts/check-layering

format:
	git ls-files '*.c' '*.h' | xargs clang-format -i

# ---- generated sources -----------------------------------------------------------
# cogw_default_config_json[]: the bytes of etc/cogw.json plus a NUL, written with
# od(1) so that no xxd is needed.
$(GEN)/default_config.c: etc/cogw.json
	@mkdir -p $(@D)
	{ echo '/* generated from etc/cogw.json by make: do not edit */'; \
	  echo '#include "apps/common/config.h"'; \
	  echo 'const char cogw_default_config_json[] = {'; \
	  od -An -v -tx1 $< | sed -e 's/\([0-9a-f][0-9a-f]\)/0x\1,/g'; \
	  echo '0x00 };'; } > $@.tmp && mv $@.tmp $@

# cogw_version[]: the one version number (file VERSION), for every program's
# --version, cogw.pc and the packages.
$(GEN)/version.c: VERSION
	@mkdir -p $(@D)
	{ echo '/* generated from VERSION by make: do not edit */'; \
	  echo '#include "apps/common/version.h"'; \
	  echo 'const char cogw_version[] = "$(VERSION)";'; } > $@.tmp && mv $@.tmp $@

# cogw_default_files[]: the files etc/cogw.json names, compiled in with it so
# that the embedded default needs nothing from the working directory.
$(GEN)/default_files.c: $(DEFAULT_FILES)
	@mkdir -p $(@D)
	{ echo '/* generated from $(DEFAULT_FILES) by make: do not edit */'; \
	  echo '#include "apps/common/config.h"'; \
	  i=0; for f in $(DEFAULT_FILES); do \
	    echo "static const char file$$i[] = {"; \
	    od -An -v -tx1 $$f | sed -e 's/\([0-9a-f][0-9a-f]\)/0x\1,/g'; \
	    echo '0x00 };'; i=$$((i + 1)); done; \
	  echo 'const cogw_embedded_file cogw_default_files[] = {'; \
	  i=0; for f in $(DEFAULT_FILES); do \
	    echo "{ \"$${f#etc/}\", file$$i, sizeof(file$$i) - 1 },"; i=$$((i + 1)); done; \
	  echo '{ 0, 0, 0 } };'; } > $@.tmp && mv $@.tmp $@

# ---- fuzz targets (libFuzzer; only where clang is installed) ---------------------
# tests/fuzz/fuzz_<name>.c -> build/fuzz/fuzz_<name>, linked with the core and
# apps/common sources compiled with -fsanitize=fuzzer. The corpora in
# tests/fuzz/corpus/<name>/ are replayed by unit tests (gcc) as well.
FUZZ_CC   ?= clang
FUZZ_SRC  := $(sort $(wildcard tests/fuzz/fuzz_*.c))
FUZZ_BINS := $(patsubst tests/fuzz/%.c,build/fuzz/%,$(FUZZ_SRC))
HAVE_FUZZ_CC := $(shell command -v $(FUZZ_CC) 2>/dev/null)
FUZZ_CFLAGS := -std=gnu11 -Wall -Wextra -Wshadow -I. -D_GNU_SOURCE -g -O1 \
	-fsanitize=fuzzer,address,undefined

.PHONY: fuzz
ifneq ($(HAVE_FUZZ_CC),)
fuzz: $(FUZZ_BINS)
# apps/common checks 1F2Ch entries with the gateway's own rules (route.c,
# convention.c: core/ only below them)
FUZZ_GATEWAY_SRC := gateway/route.c gateway/convention.c
build/fuzz/%: tests/fuzz/%.c $(CORE_SRC) $(APPCOMMON_SRC) $(APPCOMMON_GEN) $(FUZZ_GATEWAY_SRC) $(MBX_PROTO_SRC) mailbox/client_api_values.c $(ASCII_LIB_SRC) $(MQTT_LIB_SRC)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -o $@ $(filter %.c,$^) $(SYS_LIBS)
else
fuzz:
	@echo "fuzz: $(FUZZ_CC) not found; fuzz targets need clang (libFuzzer). The corpora still run in 'make unit'."
endif

# ---- benchmarks ----------------------------------------------------------------
# tests/bench/bench_vcan_*.c need vcan lines and the release daemon/simulator:
# they run through the vcan harness (4 lines, in the VM where needed); the
# other bench_*.c are core-only and run natively. Both link the bench support
# and the integration tests' process/CAN helpers and SDO requester (release
# build).
BENCH_VCAN_BINS := $(filter $(REL)/tests/bench/bench_vcan_%,$(BENCH_BINS))
BENCH_CORE_BINS := $(filter-out $(BENCH_VCAN_BINS),$(BENCH_BINS))
BENCH_SUP_OBJS  := $(call obj,$(REL),$(sort $(wildcard tests/bench/support/*.c)) tests/integration/support/proc.c tests/integration/support/sdo_req.c)
BENCH_OUT := build/bench/output.txt

# bench_vcan_mqtt is a libmosquitto client (linked only where used: --as-needed).
$(REL)/tests/bench/%: $(REL)/obj/tests/bench/%.o $(BENCH_SUP_OBJS) $(REL_LIBS)
	@mkdir -p $(@D)
	$(CC) -Wl,--as-needed -o $@ $^ $(PROGRAM_LIBS_cogw-mqtt) $(SYS_LIBS)

# The cost breakdown behind docs/fastpath.md: system calls and context
# switches per mailbox round trip and per event, counted with strace in the
# vcan harness (counts, not timings).
bench-costs: all $(REL)/tests/bench/probe_mbx_loop
	tests/vcan/run -n 2 -- tests/bench/costs

# The one-shot cogwctl and its baseline on an ftrace time line, phase by
# phase (docs/fastpath.md "One-shot `cogwctl`"); figures only.
bench-timeline: all $(REL)/tests/bench/bench_vcan_mailbox
	tests/vcan/run -n 1 -- tests/bench/oneshot-timeline

# Figures only, never pass/fail: all output goes to $(BENCH_OUT) as well, and
# tests/bench/report turns it into docs/benchmarks.md.
# A benchmark that fails prints "bench: ... FAILED", which makes the report
# (and so `make bench`) fail after docs/benchmarks.md is written.
bench: all $(BENCH_BINS)
	@mkdir -p $(dir $(BENCH_OUT))
	@{ tests/bench/run-core $(BENCH_CORE_BINS); \
	   tests/vcan/run -n 4 -- tests/bench/run-vcan $(BENCH_VCAN_BINS) || \
	   echo "bench: tests/vcan/run FAILED (status $$?)"; } 2>&1 | tee $(BENCH_OUT)
	@tests/bench/report $(BENCH_OUT) docs/benchmarks.md

# ---- demo ----------------------------------------------------------------------
demo:
	@scripts/deps.sh
	@$(MAKE) --no-print-directory all
	tests/vcan/run -n 3 -- scripts/demo.sh

# ---- install -------------------------------------------------------------------
# Applications include "mailbox/cogw.h" with `pkg-config --cflags cogw` (that is
# -I$(includedir)/cogw) and link `pkg-config --libs cogw` (-lcogw). The units'
# ExecStart and configuration paths are rewritten to bindir and sysconfdir; the
# daemon runs as the system user cogw (sysusers.d/cogw.conf: `systemd-sysusers`
# creates it, and so does `make install` when DESTDIR is empty), with the
# message-queue limits of sysctl.d/60-cogw.conf. Configuration files already there
# are kept.
COGW_PC := $(REL)/cogw.pc
$(COGW_PC): etc/cogw.pc.in VERSION
	@mkdir -p $(@D)
	@sed -e 's|@VERSION@|$(VERSION)|; s|@prefix@|$(prefix)|; s|@includedir@|$(includedir)|; s|@libdir@|$(libdir)|' $< > $@.tmp && mv $@.tmp $@
.PHONY: $(COGW_PC)
all: $(COGW_PC)

unit_paths = sed -e 's|/usr/local/bin/|$(bindir)/|; s|/etc/cogw/|$(sysconfdir)/cogw/|g; s|file:///usr/share/doc/cogw/|file://$(docdir)/|'
install_config = test -e $(DESTDIR)$(sysconfdir)/cogw/$(notdir $(1)) || \
	{ sed 's|/etc/cogw/|$(sysconfdir)/cogw/|g' $(1) > $(DESTDIR)$(sysconfdir)/cogw/$(notdir $(1)) && \
	  chmod 644 $(DESTDIR)$(sysconfdir)/cogw/$(notdir $(1)); }
install: all
	install -d $(DESTDIR)$(libdir) $(DESTDIR)$(bindir) $(DESTDIR)$(UNITDIR) \
		$(DESTDIR)$(includedir)/cogw/core $(DESTDIR)$(includedir)/cogw/mailbox \
		$(DESTDIR)$(pkgconfigdir) $(DESTDIR)$(sysconfdir)/cogw \
		$(DESTDIR)$(prefix)/lib/sysusers.d $(DESTDIR)$(prefix)/lib/sysctl.d $(DESTDIR)$(docdir)/docs \
		$(DESTDIR)$(mandir)/man1 $(DESTDIR)$(mandir)/man8
	install -m 644 $(REL_CORE_LIB) $(REL_COGW_LIB) $(DESTDIR)$(libdir)/
	install -m 755 $(REL)/lib/libcogw.so.1 $(DESTDIR)$(libdir)/
	ln -sf libcogw.so.1 $(DESTDIR)$(libdir)/libcogw.so
	install -m 644 $(COGW_PC) $(DESTDIR)$(pkgconfigdir)/cogw.pc
	install -m 644 core/*.h $(DESTDIR)$(includedir)/cogw/core/
	install -m 644 mailbox/cogw.h mailbox/proto.h mailbox/proto_app.h mailbox/proto_appwd.h mailbox/proto_health.h mailbox/cogw_health.h \
		mailbox/proto_scan.h mailbox/cogw_scan.h \
		$(DESTDIR)$(includedir)/cogw/mailbox/
	$(if $(PROGRAM_BINS),install -m 755 $(PROGRAM_BINS) $(DESTDIR)$(bindir)/)
	for u in cogwd.service cogw-ascii.service cogw-mqtt.service cogw-ascii.socket; do \
		$(unit_paths) etc/$$u > $(DESTDIR)$(UNITDIR)/$$u && chmod 644 $(DESTDIR)$(UNITDIR)/$$u || exit 1; done
	install -m 644 etc/cogw.sysusers $(DESTDIR)$(prefix)/lib/sysusers.d/cogw.conf
	install -m 644 etc/cogw.sysctl $(DESTDIR)$(prefix)/lib/sysctl.d/60-cogw.conf
	install -m 644 README.md $(DESTDIR)$(docdir)/
	install -m 644 docs/*.md $(DESTDIR)$(docdir)/docs/
	install -m 644 man/*.1 $(DESTDIR)$(mandir)/man1/
	install -m 644 man/*.8 $(DESTDIR)$(mandir)/man8/
	$(call install_config,etc/cogw.json)
	$(call install_config,etc/cogw-ascii.json)
	$(call install_config,etc/cogw-mqtt.json)
	$(call install_config,etc/transducer.dcf)
	if [ -z "$(DESTDIR)" ] && command -v systemd-sysusers >/dev/null; then \
		systemd-sysusers $(prefix)/lib/sysusers.d/cogw.conf; fi

# `make deps ARCH=arm64` adds the cross toolchain, multiarch -dev packages and
# qemu-user for `make cross`/`cross-test`; `make deps DEB=1` the packaging tools
# (debhelper, lintian, debootstrap) for `make deb`/`deb-vm-test`.
deps:
	COGW_DEPS_ARCH="$(ARCH)" COGW_DEPS_DEB="$(DEB)" scripts/deps.sh

clean:
	rm -rf build

-include $(shell find build -path build/deb -prune -o -name '*.d' -type f -print 2>/dev/null)

# ---- mailbox libraries (mailbox/*.c) ---------------------------------------------
# libcogw_mbxsrv.a: the daemon side, linked into lines/apps; libcogw.a and
# libcogw.so: the client library for applications (public header mailbox/cogw.h).
# (MBX_PROTO_SRC, MBX_SERVER_SRC, MBX_CLIENT_SRC: defined with the library names above)

$(REL)/pic/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(REL_CFLAGS) -fPIC -fvisibility=default -c $< -o $@

$(REL_MBXSRV_LIB): $(call obj,$(REL),$(MBX_SERVER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_MBXSRV_LIB): $(call obj,$(SAN),$(MBX_SERVER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(REL_COGW_LIB): $(call obj,$(REL),$(MBX_CLIENT_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

$(SAN_COGW_LIB): $(call obj,$(SAN),$(MBX_CLIENT_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^

# core/sdo_abort.c: the SDO abort codes' names (sdo_abort_to_string, core/sdo.h)
# travel with the shared library, for clients that have no core/ of their own
# (the Python package, docs/python.md); the static libcogw.a goes with libcogw_core.a.
COGW_SO_SRC := $(MBX_CLIENT_SRC) core/sdo_abort.c
$(REL_COGW_SO): $(patsubst %.c,$(REL)/pic/%.o,$(COGW_SO_SRC))
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(LDFLAGS) -shared -Wl,-soname,libcogw.so.1 -o $@.1 $^ -lrt -lpthread -lm
	ln -sf libcogw.so.1 $@

all: $(REL_COGW_SO)

# ---- cross builds (docs/install.md "Cross builds") ---------------------------------
# ARCH: a Debian architecture (arm64, armhf). Debian's cross toolchain
# (crossbuild-essential-ARCH), its pkg-config and the multiarch -dev packages
# come with `make deps ARCH=...`. Everything goes to build/ARCH/{rel,san}.
# cross-test runs the cross-built unit tests (ASan+UBSan) under qemu-user
# (binfmt not needed: the emulator is called by name). The target's C library
# and sanitizer run-times are the multiarch packages (libc6:ARCH, libasan8:ARCH)
# in /lib/TRIPLET, found by the target's own ld.so: no `qemu -L /usr/TRIPLET`,
# whose cross ld.so paired with the multiarch libc hangs in pthread_create.
# LeakSanitizer cannot run under qemu-user (it needs ptrace): leaks are checked
# by the native suite.
ARCH ?=
CROSS_TRIPLET = $(shell dpkg-architecture -a$(ARCH) -qDEB_HOST_GNU_TYPE 2>/dev/null)
CROSS_VARS = CC=$(CROSS_TRIPLET)-gcc AR=$(CROSS_TRIPLET)-ar PKG_CONFIG=$(CROSS_TRIPLET)-pkg-config \
	REL=build/$(ARCH)/rel SAN=build/$(ARCH)/san
CROSS_QEMU = qemu-$(patsubst aarch64%,aarch64,$(patsubst arm-%,arm,$(CROSS_TRIPLET)))
cross-check-arch:
	@test -n "$(ARCH)" || { echo "say which: make $(MAKECMDGOALS) ARCH=arm64 (or armhf)"; exit 2; }
	@command -v $(CROSS_TRIPLET)-gcc >/dev/null || { echo "no $(CROSS_TRIPLET)-gcc: run make deps ARCH=$(ARCH)"; exit 2; }

cross: cross-check-arch
	$(MAKE) --no-print-directory all $(CROSS_VARS)

cross-test: cross-check-arch
	$(MAKE) --no-print-directory $(patsubst $(SAN)/%,build/$(ARCH)/san/%,$(UNIT_BINS)) $(CROSS_VARS)
	COGW_TEST_EMULATOR="$(CROSS_QEMU)" ASAN_OPTIONS=detect_leaks=0 \
		tests/run-tests unit-$(ARCH) $(patsubst $(SAN)/%,build/$(ARCH)/san/%,$(UNIT_BINS))

# ---- Debian packages (debian/, docs/install.md "Debian packages") -------------------
# dpkg-buildpackage on a copy of the tree (the files git knows, as they are
# now) in build/deb/ARCH, so that its clean step leaves build/ alone; the
# packages and lintian's report end up in build/deb/ARCH. ARCH empty: this
# machine's architecture; ARCH=arm64 cross-builds (make deps ARCH=arm64 DEB=1).
DEB_OUT = build/deb/$(or $(ARCH),$(shell dpkg --print-architecture))
deb:
	rm -rf $(DEB_OUT) && mkdir -p $(DEB_OUT)/cogw-$(VERSION)
	git ls-files -co --exclude-standard -z | tar --null -T - -cf - | tar -xf - -C $(DEB_OUT)/cogw-$(VERSION)
	cd $(DEB_OUT)/cogw-$(VERSION) && dpkg-buildpackage -us -uc -b $(if $(ARCH),-a$(ARCH))
	lintian --info --display-info $(DEB_OUT)/*.changes 2>&1 | tee $(DEB_OUT)/lintian.txt
	@! grep -q '^E:' $(DEB_OUT)/lintian.txt || { echo "deb: lintian reports errors ($(DEB_OUT)/lintian.txt)"; exit 1; }

# The amd64 packages installed and run as a user would, in a clean Debian root
# inside the VM (tests/pkg/vm-install says what is checked); the root comes from
# tests/pkg/make-debroot (debootstrap) once.
DEBROOT ?= build/debroot/$(shell . /etc/os-release && echo $$VERSION_CODENAME)-amd64.tar
.PHONY: deb-vm-test
deb-vm-test:
	test -f $(DEBROOT) || tests/pkg/make-debroot $(DEBROOT)
	test -f build/deb/amd64/cogwd_$(VERSION)_amd64.deb || $(MAKE) --no-print-directory deb
	tests/vcan/run -n 3 -- tests/pkg/vm-install $(DEBROOT) build/deb/amd64

# Stripped sizes (this machine's build and the cross builds of FOOTPRINT_ARCHS,
# `make cross ARCH=...` first) and cogwd's resident memory, written into
# docs/benchmarks.md's "Footprint" section (tests/bench/footprint).
FOOTPRINT_ARCHS ?= arm64 armhf
.PHONY: footprint
footprint: all
	@mkdir -p build/bench
	tests/vcan/run -n 4 -- tests/bench/footprint measure $(FOOTPRINT_ARCHS) 2>&1 | tee build/bench/footprint.out
	tests/bench/footprint into docs/benchmarks.md build/bench/footprint.out

# Integration tests of a cross build on vcan, in the VM, under qemu-user: the
# tests of CROSS_INTEG_TESTS cross-built (ASan+UBSan), and the daemon the other
# tests start (COGW_TEST_COGWD) is the cross-built one behind qemu-user as well;
# the simulated devices (cosim) stay native. What qemu-user cannot emulate
# shows as a failure here, not in `make test`: qemu 7.2 (bookworm) refuses
# SO_TIMESTAMPNS and CAN_RAW_ERR_FILTER, so the CAN tests fail at their first
# socket there (docs/install.md "Cross builds").
CROSS_INTEG_TESTS ?= test_socketcan test_line_socketcan test_mqueue test_line_sdo test_manager_boot test_config_boot
.PHONY: cross-integration
cross-integration: cross-check-arch $(SAN_PROGRAM_BINS)
	$(MAKE) --no-print-directory $(addprefix build/$(ARCH)/san/tests/integration/,$(CROSS_INTEG_TESTS)) \
		build/$(ARCH)/san/bin/cogwd $(CROSS_VARS)
	printf '#!/bin/sh\nexec %s %s "$$@"\n' "$(CROSS_QEMU)" \
		"$(CURDIR)/build/$(ARCH)/san/bin/cogwd" > build/$(ARCH)/cogwd-emulated
	chmod +x build/$(ARCH)/cogwd-emulated
	tests/vcan/run -n 3 -- env COGW_TEST_EMULATOR="$(CROSS_QEMU)" \
		ASAN_OPTIONS=detect_leaks=0 COGW_TEST_COGWD=$(CURDIR)/build/$(ARCH)/cogwd-emulated \
		tests/run-tests integration-$(ARCH) $(addprefix build/$(ARCH)/san/tests/integration/,$(CROSS_INTEG_TESTS))
