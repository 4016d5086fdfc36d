# cogw — top-level build. `make` builds everything; `make test` runs the whole suite
# (unit tests natively, integration tests on vcan lines, in a VM where needed);
# `make demo` runs the gateway demo; `make deps` installs what all of this needs.
#
# Two configurations live side by side:
#   build/rel  -O2, what `make`, `make install` and `make bench` use;
#   build/san  ASan+UBSan, what the tests use;
# and a third for what threads share:
#   build/tsan ThreadSanitizer, the multi-threaded stress tests in tests/tsan/.

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
GATEWAY_SRC := $(sort $(wildcard gateway/*.c))
MANAGER_SRC := $(sort $(wildcard manager/*.c))
DEVOBJ_SRC  := $(sort $(wildcard devobj/*.c))
APPCOMMON_SRC := $(sort $(wildcard apps/common/*.c))
# Generated at build time, never committed: etc/cogw.json as a C string.
GEN := build/gen
APPCOMMON_GEN := $(GEN)/default_config.c $(GEN)/default_files.c
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
# mailbox: libcogw_mbxsrv.a (daemon side, proto.c + server.c) and libcogw.a/.so
# (client library, proto.c + client.c + client_api_*.c); rules at the end of this file.
REL_MBXSRV_LIB := $(REL)/lib/libcogw_mbxsrv.a
SAN_MBXSRV_LIB := $(SAN)/lib/libcogw_mbxsrv.a
REL_COGW_LIB := $(REL)/lib/libcogw.a
SAN_COGW_LIB := $(SAN)/lib/libcogw.a
REL_COGW_SO := $(REL)/lib/libcogw.so
REL_LIBS = $(REL_APPCOMMON_LIB) $(REL_DEVOBJ_LIB) $(REL_MANAGER_LIB) $(REL_GATEWAY_LIB) $(REL_LINES_LIB) $(REL_MBXSRV_LIB) $(REL_COGW_LIB) $(REL_CORE_LIB)
SAN_LIBS = $(SAN_APPCOMMON_LIB) $(SAN_DEVOBJ_LIB) $(SAN_MANAGER_LIB) $(SAN_GATEWAY_LIB) $(SAN_LINES_LIB) $(SAN_MBXSRV_LIB) $(SAN_COGW_LIB) $(SAN_CORE_LIB)
SYS_LIBS := $(shell pkg-config --libs libcjson libsystemd 2>/dev/null || echo -lcjson -lsystemd) -lrt -lpthread -lm
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
TSAN_LIB_SRC := $(LINES_SRC) $(GATEWAY_SRC) mailbox/proto.c mailbox/client.c \
		$(sort $(wildcard mailbox/client_api_*.c)) mailbox/server.c mailbox/budget.c
TSAN_CORE_LIB := $(TSAN)/lib/libcogw-core.a
TSAN_BINS := $(patsubst tests/tsan/%.c,$(TSAN)/tests/tsan/%,$(TSAN_SRC))
TSAN_VCAN_BINS := $(patsubst tests/tsan/%.c,$(TSAN)/tests/tsan/%,$(TSAN_VCAN_SRC))
BENCH_BINS := $(patsubst tests/bench/%.c,$(REL)/tests/bench/%,$(BENCH_SRC))

.PHONY: all deps test unit tsan integration interop bench bench-costs bench-timeline demo install clean tests-build check check-core-io check-layering format check-callgraph
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

$(REL_GATEWAY_LIB): $(call obj,$(REL),$(GATEWAY_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_GATEWAY_LIB): $(call obj,$(SAN),$(GATEWAY_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(REL_MANAGER_LIB): $(call obj,$(REL),$(MANAGER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_MANAGER_LIB): $(call obj,$(SAN),$(MANAGER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(REL_DEVOBJ_LIB): $(call obj,$(REL),$(DEVOBJ_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_DEVOBJ_LIB): $(call obj,$(SAN),$(DEVOBJ_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# The ASCII gateway's parser, value texts and configuration loader: linked into the unit
# tests and the fuzz targets as well as into apps/cogw-ascii.
ASCII_LIB_SRC := apps/cogw-ascii/ascii_parse.c apps/cogw-ascii/ascii_value.c apps/cogw-ascii/ascii_config.c
SAN_ASCII_LIB := $(SAN)/lib/libcogw_ascii.a
$(SAN_ASCII_LIB): $(call obj,$(SAN),$(ASCII_LIB_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# The MQTT bridge's request decoder and configuration loader: linked into the unit
# tests and the fuzz targets as well as into apps/cogw-mqtt (no libmosquitto in them).
MQTT_LIB_SRC := apps/cogw-mqtt/mqtt_request.c apps/cogw-mqtt/mqtt_config.c
SAN_MQTT_LIB := $(SAN)/lib/libcogw_mqtt.a
$(SAN_MQTT_LIB): $(call obj,$(SAN),$(MQTT_LIB_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(REL_APPCOMMON_LIB): $(call obj,$(REL),$(APPCOMMON_SRC) $(APPCOMMON_GEN))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_APPCOMMON_LIB): $(call obj,$(SAN),$(APPCOMMON_SRC) $(APPCOMMON_GEN))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# ---- programs: apps/<name>/*.c -> build/<cfg>/bin/<name> -----------------------
# The sanitizer build of the programs is what the integration tests run.
# PROGRAM_SRC_<name>: sources of other directories a program links too;
# PROGRAM_LIBS_<name>: system libraries only it needs.
PROGRAM_SRC_cogw-mqtt := apps/cogw-ascii/ascii_value.c
PROGRAM_LIBS_cogw-mqtt := $(shell pkg-config --libs libmosquitto 2>/dev/null || echo -lmosquitto)
define program_rules
$(REL)/bin/$(1): $(call obj,$(REL),$(wildcard apps/$(1)/*.c) $(PROGRAM_SRC_$(1))) $$(REL_LIBS)
	@mkdir -p $$(@D)
	$$(CC) -o $$@ $$^ $$(PROGRAM_LIBS_$(1)) $$(SYS_LIBS)
$(SAN)/bin/$(1): $(call obj,$(SAN),$(wildcard apps/$(1)/*.c) $(PROGRAM_SRC_$(1))) $$(SAN_LIBS)
	@mkdir -p $$(@D)
	$$(CC) $$(SAN_LDFLAGS) -o $$@ $$^ $$(PROGRAM_LIBS_$(1)) $$(SYS_LIBS)
endef
$(foreach p,$(PROGRAMS),$(eval $(call program_rules,$(p))))

# ---- tests ---------------------------------------------------------------------
$(SAN)/tests/unit/%: $(SAN)/obj/tests/unit/%.o $(call obj,$(SAN),$(UNIT_SUP)) $(SAN)/obj/unity.o $(SAN_MQTT_LIB) $(SAN_ASCII_LIB) $(SAN_LIBS)
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
	rm -f $@ && ar rcs $@ $^

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
INTEROP_TESTS := tests/interop/run tests/interop/run-mqtt
interop: $(SAN_PROGRAM_BINS)
	@scripts/pyenv.sh
	tests/vcan/run -n 3 -- env COGW_TEST_TIMEOUT=$${COGW_INTEROP_TIMEOUT:-1800} tests/run-tests interop $(INTEROP_TESTS)

# The MQTT group alone (one VM boot).
.PHONY: interop-mqtt
interop-mqtt: $(SAN_PROGRAM_BINS)
	@scripts/pyenv.sh
	tests/vcan/run -n 3 -- tests/run-tests mqtt tests/interop/run-mqtt

# The whole suite: set-up if needed, build, unit tests, then integration tests on
# 3 vcan lines and the interoperability group in the same VM boot; one closing
# line "N passed, M failed".
test:
	@scripts/deps.sh
	@scripts/pyenv.sh
	@$(MAKE) --no-print-directory all tests-build
	@tests/run-all "$(UNIT_BINS)" "$(INTEG_BINS) $(TSAN_VCAN_BINS)" "$(TSAN_BINS)" "$(INTEROP_TESTS)"

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
build/fuzz/%: tests/fuzz/%.c $(CORE_SRC) $(APPCOMMON_SRC) $(APPCOMMON_GEN) $(FUZZ_GATEWAY_SRC) mailbox/proto.c mailbox/client_api_values.c $(ASCII_LIB_SRC) $(MQTT_LIB_SRC)
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
# Applications include "mailbox/cogw.h" with -I$(PREFIX)/include/cogw and link
# -lcogw. The unit's ExecStart is rewritten to the installed binary.
SYSCONFDIR ?= /etc
UNITDIR ?= $(PREFIX)/lib/systemd/system
install: all
	install -d $(DESTDIR)$(PREFIX)/lib $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(UNITDIR) \
		$(DESTDIR)$(PREFIX)/include/cogw/core $(DESTDIR)$(PREFIX)/include/cogw/mailbox \
		$(DESTDIR)$(SYSCONFDIR)/cogw
	install -m 644 $(REL_CORE_LIB) $(REL_COGW_LIB) $(DESTDIR)$(PREFIX)/lib/
	cp -P $(REL)/lib/libcogw.so* $(DESTDIR)$(PREFIX)/lib/
	install -m 644 core/*.h $(DESTDIR)$(PREFIX)/include/cogw/core/
	install -m 644 mailbox/cogw.h mailbox/proto.h mailbox/proto_health.h mailbox/cogw_health.h $(DESTDIR)$(PREFIX)/include/cogw/mailbox/
	$(if $(PROGRAM_BINS),install -m 755 $(PROGRAM_BINS) $(DESTDIR)$(PREFIX)/bin/)
	sed 's|/usr/local/bin/cogwd|$(PREFIX)/bin/cogwd|; s|/etc/cogw/|$(SYSCONFDIR)/cogw/|' etc/cogwd.service \
		> $(DESTDIR)$(UNITDIR)/cogwd.service
	test -e $(DESTDIR)$(SYSCONFDIR)/cogw/cogw.json || install -m 644 etc/cogw.json $(DESTDIR)$(SYSCONFDIR)/cogw/cogw.json
	sed 's|/usr/local/bin/cogw-ascii|$(PREFIX)/bin/cogw-ascii|; s|/etc/cogw/|$(SYSCONFDIR)/cogw/|' etc/cogw-ascii.service \
		> $(DESTDIR)$(UNITDIR)/cogw-ascii.service
	install -m 644 etc/cogw-ascii.socket $(DESTDIR)$(UNITDIR)/cogw-ascii.socket
	test -e $(DESTDIR)$(SYSCONFDIR)/cogw/cogw-ascii.json || sed 's|/etc/cogw/|$(SYSCONFDIR)/cogw/|' etc/cogw-ascii.json \
		> $(DESTDIR)$(SYSCONFDIR)/cogw/cogw-ascii.json
	sed 's|/usr/local/bin/cogw-mqtt|$(PREFIX)/bin/cogw-mqtt|; s|/etc/cogw/|$(SYSCONFDIR)/cogw/|' etc/cogw-mqtt.service \
		> $(DESTDIR)$(UNITDIR)/cogw-mqtt.service
	test -e $(DESTDIR)$(SYSCONFDIR)/cogw/cogw-mqtt.json || sed 's|/etc/cogw/|$(SYSCONFDIR)/cogw/|' etc/cogw-mqtt.json \
		> $(DESTDIR)$(SYSCONFDIR)/cogw/cogw-mqtt.json
	test -e $(DESTDIR)$(SYSCONFDIR)/cogw/transducer.dcf || install -m 644 etc/transducer.dcf $(DESTDIR)$(SYSCONFDIR)/cogw/transducer.dcf

deps:
	scripts/deps.sh

clean:
	rm -rf build

-include $(shell find build -name '*.d' 2>/dev/null)

# ---- mailbox libraries (mailbox/*.c) ---------------------------------------------
# libcogw_mbxsrv.a: the daemon side, linked into lines/apps; libcogw.a and
# libcogw.so: the client library for applications (public header mailbox/cogw.h).
MBX_PROTO_SRC  := mailbox/proto.c
MBX_SERVER_SRC := $(MBX_PROTO_SRC) mailbox/server.c mailbox/budget.c
MBX_CLIENT_SRC := $(MBX_PROTO_SRC) mailbox/client.c $(sort $(wildcard mailbox/client_api_*.c))

$(REL)/pic/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(REL_CFLAGS) -fPIC -fvisibility=default -c $< -o $@

$(REL_MBXSRV_LIB): $(call obj,$(REL),$(MBX_SERVER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_MBXSRV_LIB): $(call obj,$(SAN),$(MBX_SERVER_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(REL_COGW_LIB): $(call obj,$(REL),$(MBX_CLIENT_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(SAN_COGW_LIB): $(call obj,$(SAN),$(MBX_CLIENT_SRC))
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(REL_COGW_SO): $(patsubst %.c,$(REL)/pic/%.o,$(MBX_CLIENT_SRC))
	@mkdir -p $(@D)
	$(CC) -shared -Wl,-soname,libcogw.so.1 -o $@.1 $^ -lrt -lpthread -lm
	ln -sf libcogw.so.1 $@

all: $(REL_COGW_SO)
