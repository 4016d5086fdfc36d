/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_cogwctl.c - the CLI end to end: the real cogwd on
 * the lines of its default configuration without a manager (the nodes are
 * started by hand here: tests/integration/config/hand-started.json), the
 * simulated transducer (node 1)
 * on vcan0, and cogwctl run as a separate process for every command, its
 * stdout, stderr and exit status checked:
 *
 *  - --help of the tool and of every subcommand: exit 0, every option named;
 *  - usage errors (exit 2) and no daemon (exit 3);
 *  - status (node table), sdo read/write with types, --json, abort codes
 *    with their meaning (exit 1), a silent device (exit 4), a 3000-byte
 *    DOMAIN through @FILE and --out, compared byte for byte;
 *  - nmt start (node and self), pressure PDO events through monitor,
 *    pdo read of the process image;
 *  - raw send (frames checked on the bus) and raw dump with a filter;
 *  - emcy: one sent by the daemon (on the bus), one received (monitor);
 *  - lss: switch, inquire, fastscan finding nobody;
 *  - two devices on one node-ID of this unmanaged line: dup-node event,
 *    status flag.
 *
 * Run from the repository root:
 *   make build/san/tests/integration/test_cogwctl build/san/bin/cogwd \
 *        build/san/bin/cosim build/san/bin/cogwctl
 *   tests/vcan/run -n 3 -- build/san/tests/integration/test_cogwctl
 */
#include <cjson/cJSON.h>
#include <errno.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

/* COGW_TEST_COGWCTL: run against another build of the tool (e.g. an
 * older one, to see a regression test fail there). */
static const char *ctl_path(void)
{
	const char *p = getenv("COGW_TEST_COGWCTL");
	return p && *p ? p : "build/san/bin/cogwctl";
}
#define CTL ctl_path()
#define DOMAIN_IDX 0x2200
#define DOMAIN_SIZE 3000u

static daemon_run dmn;
static cosim_run sim;
static cosim_run twin;  /* a second device on node 1 */
static char tmpdir[64]; /* for tests without a daemon */

/* One finished cogwctl run. */
typedef struct ctl_result {
	int exit;        /* exit status, -1 if it did not exit normally */
	char out[16384]; /* stdout */
	char err[4096];  /* stderr */
} ctl_result;

static ctl_result res;

static const char *work_dir(void)
{
	return dmn.dir[0] ? dmn.dir : tmpdir;
}

static void slurp(const char *path, char *buf, size_t cap)
{
	buf[0] = '\0';
	FILE *f = fopen(path, "r");
	if (!f)
		return;
	size_t n = fread(buf, 1, cap - 1, f);
	buf[n] = '\0';
	fclose(f);
}

/* Run "cogwctl ARGS" (through sh: ARGS may quote) and wait for it. */
static ctl_result *ctl_run(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static ctl_result *ctl_run(const char *fmt, ...)
{
	char args[1024], cmd[1400], out_path[128], err_path[128];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(args, sizeof args, fmt, ap);
	va_end(ap);
	snprintf(out_path, sizeof out_path, "%s/ctl.out", work_dir());
	snprintf(err_path, sizeof err_path, "%s/ctl.err", work_dir());
	snprintf(cmd, sizeof cmd, "%s %s >%s 2>%s", CTL, args, out_path, err_path);
	int st = system(cmd);
	res.exit = (st != -1 && WIFEXITED(st)) ? WEXITSTATUS(st) : -1;
	slurp(out_path, res.out, sizeof res.out);
	slurp(err_path, res.err, sizeof res.err);
	return &res;
}

/* A cogwctl started in the background (monitor, raw dump); collect with
 * bg_finish once it has ended by --count/--duration. */
typedef struct bg_ctl {
	pid_t pid;
	char out_path[128], err_path[128];
} bg_ctl;

static bg_ctl bg;

static void bg_start(const char *args)
{
	char cmd[1400];
	snprintf(bg.out_path, sizeof bg.out_path, "%s/bg.out", work_dir());
	snprintf(bg.err_path, sizeof bg.err_path, "%s/bg.err", work_dir());
	/* The files of the previous background cogwctl of this test must not
	 * survive into this one: its "watching" line would let
	 * wait_subscribed() return before this cogwctl has even started, and
	 * an event sent right after would be missed (seen as an empty stdout
	 * after --duration under load). */
	unlink(bg.out_path);
	unlink(bg.err_path);
	snprintf(cmd, sizeof cmd, "exec %s %s >%s 2>%s", CTL, args, bg.out_path, bg.err_path);
	const char *argv[] = { "/bin/sh", "-c", cmd, NULL };
	bg.pid = proc_spawn(argv, NULL, NULL);
	TEST_ASSERT_TRUE(bg.pid > 0);
}

static ctl_result *bg_finish(int timeout_ms)
{
	int st = 0;
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	while (!proc_exited(bg.pid, &st)) {
		if (mono_ms() > until) {
			proc_stop(bg.pid, SIGKILL, 1000);
			bg.pid = 0;
			TEST_FAIL_MESSAGE("background cogwctl did not end in time");
		}
		sleep_ms(50);
	}
	bg.pid = 0;
	res.exit = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
	slurp(bg.out_path, res.out, sizeof res.out);
	slurp(bg.err_path, res.err, sizeof res.err);
	return &res;
}

static void expect_exit(int code, const ctl_result *r)
{
	if (r->exit != code) {
		printf("stdout: %s\nstderr: %s\n", r->out, r->err);
		TEST_ASSERT_EQUAL_INT(code, r->exit);
	}
}

static void expect_contains(const char *hay, const char *needle)
{
	if (!strstr(hay, needle)) {
		printf("expected \"%s\" in:\n%s\n", needle, hay);
		TEST_FAIL_MESSAGE("text missing");
	}
}

/* Wait until a background monitor / raw dump has subscribed: it says so
 * on stderr once the daemon has acknowledged its subscriptions. */
static void wait_subscribed(void)
{
	if (!file_wait_contains(bg.err_path, "watching", 10000)) {
		proc_dump_log(bg.err_path, 10);
		TEST_FAIL_MESSAGE("background cogwctl never subscribed");
	}
}

/* The transducer with a writable DOMAIN object for the large-transfer test. */
static void write_device_copy(const char *dst)
{
	FILE *f = fopen("etc/devices/sti-pressure.json", "r");
	TEST_ASSERT_NOT_NULL(f);
	static char text[65536];
	size_t n = fread(text, 1, sizeof text - 1, f);
	fclose(f);
	text[n] = '\0';
	cJSON *root = cJSON_Parse(text);
	TEST_ASSERT_NOT_NULL(root);
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "index", "0x2200");
	cJSON_AddStringToObject(o, "name", "test domain");
	cJSON_AddStringToObject(o, "type", "DOMAIN");
	cJSON_AddStringToObject(o, "access", "rw");
	cJSON_AddNumberToObject(o, "max_size", 65536);
	cJSON_AddItemToArray(cJSON_GetObjectItem(root, "objects"), o);
	char *out = cJSON_Print(root);
	TEST_ASSERT_EQUAL_INT(0, write_text_file(dst, out));
	free(out);
	cJSON_Delete(root);
}

/* cogwd (instance "main", no manager: node 1 stays pre-operational until
 * a test starts it) + the transducer on vcan0; returns once the daemon's
 * node table lists node 1. */
static void start_system(void)
{
	TEST_ASSERT_EQUAL_INT(
		0, daemon_start(&dmn, &(daemon_opts){ .config_file = HAND_STARTED, .n_lines = 3 }));
	char dev[DAEMON_PATH_MAX + 16];
	snprintf(dev, sizeof dev, "%s/pt.json", dmn.dir);
	write_device_copy(dev);
	const char *devices[] = { dev, NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, NULL));
	uint64_t until = mono_ms() + 10000;
	for (;;) {
		ctl_result *r = ctl_run("--json status 0");
		/* supervised from the start, but in the table with a state only
		 * once its boot-up and first heartbeat were heard */
		if (r->exit == 0 && strstr(r->out, "\"node\":1,\"nmt_state\":\"pre-operational\""))
			break;
		TEST_ASSERT_TRUE_MESSAGE(mono_ms() < until,
					 "node 1 never appeared in the node table");
		sleep_ms(200);
	}
}

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim, 0, sizeof sim);
	memset(&twin, 0, sizeof twin);
	memset(&bg, 0, sizeof bg);
	snprintf(tmpdir, sizeof tmpdir, "/tmp/test_cogwctl.XXXXXX");
	TEST_ASSERT_NOT_NULL(mkdtemp(tmpdir));
}

void tearDown(void)
{
	if (bg.pid > 0)
		proc_stop(bg.pid, SIGKILL, 1000);
	bg.pid = 0;
	cosim_stop(&sim, 3000);
	cosim_stop(&twin, 3000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues("main");
	char cmd[128];
	snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
	if (system(cmd) != 0)
		printf("could not remove %s\n", tmpdir);
}

/* ---- without a daemon ------------------------------------------------------ */

static void test_help_documents_every_subcommand(void)
{
	static const struct {
		const char *cmd;
		const char *mentions[7];
	} cases[] = {
		{ "status", { "LINE", "node table", NULL } },
		{ "sdo", { "--out", "--mode", "--sdo-timeout", "@FILE", "abort", "TYPE", NULL } },
		{ "od", { "--out", "INDEX", NULL } },
		{ "nmt", { "start", "stop", "preop", "reset-node", "reset-comm", "self", NULL } },
		{ "pdo", { "request", "read", "write", "--trigger", NULL } },
		{ "emcy", { "send", "CODE", "REGISTER", NULL } },
		{ "lss",
		  { "fastscan", "set-node-id", "set-bit-timing", "store", "--kbit", "inquire",
		    NULL } },
		{ "monitor",
		  { "--line", "--class", "--raw-filter", "--count", "--duration", "--float",
		    NULL } },
		{ "raw", { "send", "dump", "--count", "--duration", "ID#DATA", NULL } },
		{ "app", { "essential", "hold", "--interval", "--react", "--rearm", NULL } },
		{ "host", { "ready", "not-ready", NULL } },
	};
	ctl_result *r = ctl_run("--help");
	expect_exit(0, r);
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		char needle[32];
		snprintf(needle, sizeof needle, "  %s ", cases[i].cmd);
		expect_contains(r->out, needle);
	}
	expect_contains(r->out, "--instance");
	expect_contains(r->out, "--json");
	expect_contains(r->out, "--timeout");
	expect_contains(r->out, "4  timeout");
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		r = ctl_run("%s --help", cases[i].cmd);
		expect_exit(0, r);
		for (size_t k = 0; cases[i].mentions[k]; k++)
			expect_contains(r->out, cases[i].mentions[k]);
		expect_contains(r->out, "Exit status");
	}
	/* --help after arguments too */
	expect_exit(0, ctl_run("sdo read 0 1 1018 1 --help"));
	expect_contains(res.out, "usage: cogwctl sdo read");
	expect_exit(0, ctl_run("--version"));
	expect_contains(res.out, "cogwctl ");
}

static void test_usage_errors_exit_2_and_no_daemon_exits_3(void)
{
	static const struct {
		const char *args;
		const char *msg;
	} cases[] = {
		{ "", "no command given" },
		{ "frobnicate", "unknown command 'frobnicate'" },
		{ "sdo read 0 200 1018 1", "NODE '200': a node-ID is 1..127" },
		{ "sdo read 0 1 10180 1", "INDEX '10180'" },
		{ "sdo read 0 1 1018 256", "SUB '256'" },
		{ "sdo read 0 1 1018 1 u33", "unknown TYPE 'u33'" },
		{ "sdo write 0 1 1017 0 u16 70000",
		  "VALUE '70000' for u16: out of range (0..65535)" },
		{ "sdo write 0 1 1017 0 i8 -129", "VALUE '-129' for i8: out of range (-128..127)" },
		{ "sdo write 0 1 1017 0 u16 12abc", "not an integer" },
		{ "sdo write 0 1 2005 1 r32 1e39", "not a finite number within +-3.4e38" },
		{ "sdo write 0 1 2200 0 hex 0g", "not a hex byte string" },
		{ "sdo write 0 1 2200 0 domain @/nonexistent/file", "/nonexistent/file" },
		{ "sdo write 0 1 1017 0 u16", "expected LINE NODE INDEX SUB TYPE VALUE" },
		{ "sdo read 0 1 1018 1 --mode fast", "--mode 'fast'" },
		{ "nmt jump 0 1", "unknown ACTION 'jump'" },
		{ "nmt start 0 0", "NODE '0'" },
		{ "raw send 0 1234#00", "frame '1234#00'" },
		{ "raw send 0 123#112233445566778899", "frame '123#112233445566778899'" },
		{ "raw dump 0 800", "filter '800'" },
		{ "monitor --class foo", "unknown event class 'foo'" },
		{ "monitor --duration -1", "--duration '-1'" },
		{ "status --bogus", "unknown option '--bogus'" },
		{ "--timeout 0 status", "--timeout needs milliseconds" },
		{ "lss set-node-id 0 128", "NODE: 1..127, or 255" },
		{ "lss set-bit-timing 0 --kbit 333",
		  "--kbit 333 is not in the CiA bit timing table" },
		{ "emcy send 0 12345", "CODE '12345'" },
		{ "app 0 essential", "app essential needs --interval MS" },
		{ "app 0 essential --interval 5", "--interval: at least 10 ms" },
		{ "app 0 essential --interval 70000", "--interval" },
		{ "app 0 essential --interval 100 --react emcy,boom", "--react: a list of" },
		{ "host 0 maybe", "host LINE ready|not-ready" },
		{ "host 0", "host LINE ready|not-ready" },
	};
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		ctl_result *r = ctl_run("%s", cases[i].args);
		if (r->exit != 2)
			printf("case '%s'\n", cases[i].args);
		expect_exit(2, r);
		expect_contains(r->err, cases[i].msg);
	}
	/* a daemon instance nobody runs */
	ctl_result *r = ctl_run("--instance nobody status");
	expect_exit(3, r);
	expect_contains(r->err, "no daemon for mailbox instance 'nobody'");
	r = ctl_run("--instance nobody sdo read 0 1 1018 1 u32");
	expect_exit(3, r);
	expect_contains(r->err, "daemon not running");
	r = ctl_run("--instance nobody --json nmt start 0 1");
	expect_exit(3, r);
	expect_contains(r->out, "\"ok\":false");
	expect_contains(r->out, "\"exit\":3");
}

/* ---- with the daemon --------------------------------------------------------- */

static void test_status_sdo_types_json_and_aborts(void)
{
	start_system();
	ctl_result *r = ctl_run("status");
	expect_exit(0, r);
	expect_contains(r->out, "line 0: CAN error-active, 1000 kbit/s, bus load ");
	expect_contains(r->out, " %, own node 127 pre-operational");
	expect_contains(r->out, "     1  pre-operational   active");
	expect_contains(r->out, "line 2:");

	expect_exit(0, ctl_run("sdo read 0 1 1018 1 u32"));
	TEST_ASSERT_EQUAL_STRING("1018:01 = 592 (0x00000250)\n", res.out);
	expect_exit(0, ctl_run("sdo read 0 1 0x1018 4"));
	TEST_ASSERT_EQUAL_STRING("1018:04 = 40 e2 01 00 (= 123456 as u32)\n", res.out);
	expect_exit(0, ctl_run("sdo read 0 1 1008 0 string"));
	TEST_ASSERT_EQUAL_STRING("1008:00 = \"STI-SIM\"\n", res.out);
	expect_exit(0, ctl_run("--json sdo read 0 1 1000h 0 UNSIGNED32"));
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL(o);
	TEST_ASSERT_TRUE(cJSON_IsTrue(cJSON_GetObjectItem(o, "ok")));
	TEST_ASSERT_EQUAL_DOUBLE(0x00040194, cJSON_GetObjectItem(o, "value")->valuedouble);
	TEST_ASSERT_EQUAL_STRING("0x1000", cJSON_GetObjectItem(o, "index")->valuestring);
	TEST_ASSERT_EQUAL_STRING("94 01 04 00", cJSON_GetObjectItem(o, "hex")->valuestring);
	cJSON_Delete(o);

	/* write, read back through the CLI and through the device itself */
	expect_exit(0, ctl_run("sdo write 0 1 1017 0 u16 500"));
	TEST_ASSERT_EQUAL_STRING("1017:00 <- 500 (0x01F4) (2 bytes): ok\n", res.out);
	expect_exit(0, ctl_run("sdo read 0 1 1017 0 u16"));
	TEST_ASSERT_EQUAL_STRING("1017:00 = 500 (0x01F4)\n", res.out);
	char reply[256];
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "get 0x1017:00", reply, sizeof reply, 3000));
	expect_contains(reply, "500");
	expect_exit(0, ctl_run("sdo write 0 1 2005 1 r32 98.5"));
	expect_exit(0, ctl_run("sdo read 0 1 2005 1 r32"));
	TEST_ASSERT_EQUAL_STRING("2005:01 = 98.5\n", res.out);

	/* refusals: the abort code with its meaning, exit 1 */
	r = ctl_run("sdo read 0 1 2001 0 u32");
	expect_exit(1, r);
	expect_contains(
		r->err,
		"SDO upload 2001:00 node 1 on line 0: abort 0x06020000 (object does not exist");
	r = ctl_run("sdo write 0 1 1018 1 u32 5");
	expect_exit(1, r);
	expect_contains(r->err, "abort 0x06010002");
	r = ctl_run("--json sdo write 0 1 1017 0 u8 5");
	expect_exit(1, r);
	expect_contains(r->out, "\"abort\":\"0x0607001"); /* length mismatch */
	/* a wrong TYPE on read: the size does not match */
	r = ctl_run("sdo read 0 1 1017 0 u32");
	expect_exit(1, r);
	expect_contains(r->err, "the answer has 2 bytes (f4 01), u32 needs 4");

	/* a device that does not answer: SDO timeout = exit 4 */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "sdo silent on", NULL, 0, 3000));
	r = ctl_run("sdo read 0 1 1018 1 u32 --sdo-timeout 300");
	expect_exit(4, r);
	expect_contains(r->err, "abort 0x05040000 (SDO protocol timed out)");
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "sdo silent off", NULL, 0, 3000));

	/* the daemon's own object dictionary */
	expect_exit(0, ctl_run("od read 0 1008 0 string"));
	TEST_ASSERT_EQUAL_STRING("1008:00 = \"cogw gateway\"\n", res.out);
	expect_exit(0, ctl_run("od read 0 1400 1 u32"));
	TEST_ASSERT_EQUAL_STRING("1400:01 = 385 (0x00000181)\n", res.out);
}

static void test_sdo_domain_from_file_and_to_file(void)
{
	start_system();
	char in[DAEMON_PATH_MAX + 16], out[DAEMON_PATH_MAX + 16];
	static uint8_t data[DOMAIN_SIZE], back[DOMAIN_SIZE + 16];
	for (unsigned i = 0; i < DOMAIN_SIZE; i++)
		data[i] = (uint8_t)(i * 7u + 3u);
	snprintf(in, sizeof in, "%s/domain.in", dmn.dir);
	snprintf(out, sizeof out, "%s/domain.out", dmn.dir);
	FILE *f = fopen(in, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(DOMAIN_SIZE, fwrite(data, 1, DOMAIN_SIZE, f));
	fclose(f);

	static const char *const modes[] = { "segmented", "block" };
	for (int m = 0; m < 2; m++) {
		ctl_result *r = ctl_run("sdo write 0 1 2200 0 domain @%s --mode %s --timeout 20000",
					in, modes[m]);
		expect_exit(0, r);
		expect_contains(r->out, "2200:00 <- @");
		expect_contains(r->out, "(3000 bytes): ok");
		unlink(out);
		r = ctl_run("sdo read 0 1 2200 0 domain --out %s --mode %s --timeout 20000", out,
			    modes[m]);
		expect_exit(0, r);
		expect_contains(r->out, "3000 bytes written to");
		f = fopen(out, "rb");
		TEST_ASSERT_NOT_NULL(f);
		size_t n = fread(back, 1, sizeof back, f);
		fclose(f);
		TEST_ASSERT_EQUAL_size_t(DOMAIN_SIZE, n);
		TEST_ASSERT_EQUAL_MEMORY(data, back, DOMAIN_SIZE);
	}
	/* hex VALUE for a domain, read back without a type */
	expect_exit(0, ctl_run("sdo write 0 1 2200 0 hex \"de ad be ef 01\""));
	expect_exit(0, ctl_run("sdo read 0 1 2200 0"));
	TEST_ASSERT_EQUAL_STRING("2200:00 = de ad be ef 01\n", res.out);
}

static void test_nmt_monitor_pdo_and_process_image(void)
{
	start_system();
	char reply[256];
	expect_exit(0, ctl_run("nmt start 0 1"));
	TEST_ASSERT_EQUAL_STRING("line 0: NMT start sent to node 1\n", res.out);
	uint64_t until = mono_ms() + 5000;
	for (;;) {
		TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "status", reply, sizeof reply, 3000));
		if (strstr(reply, "operational") && !strstr(reply, "pre-operational"))
			break;
		TEST_ASSERT_TRUE_MESSAGE(mono_ms() < until, reply);
		sleep_ms(100);
	}
	expect_exit(0, ctl_run("nmt start 0 self"));
	TEST_ASSERT_EQUAL_STRING("line 0: NMT start sent to node 127 (the daemon itself)\n",
				 res.out);
	expect_exit(0, ctl_run("status 0"));
	expect_contains(res.out, "own node 127 operational");

	/* hold the pressure at a known value: (raw + 2004h:1) * 2005h:1 / 100 */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "pressure 20", NULL, 0, 3000));
	/* the next TPDOs (event timer 1 s) carry 20.0 */
	bg_start("monitor --line 0 --class pdo --float --count 3 --duration 20");
	ctl_result *r = bg_finish(30000);
	expect_exit(0, r);
	expect_contains(r->out, "line 0 pdo   RPDO 1: B000:00 = 20\n");
	expect_contains(r->err, "3 events");

	bg_start("--json monitor --line 0 --class pdo --count 1 --duration 20");
	r = bg_finish(30000);
	expect_exit(0, r);
	cJSON *o = cJSON_Parse(r->out);
	TEST_ASSERT_NOT_NULL(o);
	TEST_ASSERT_EQUAL_STRING("pdo", cJSON_GetObjectItem(o, "class")->valuestring);
	TEST_ASSERT_EQUAL_INT(1, cJSON_GetObjectItem(o, "pdo")->valueint);
	cJSON *v = cJSON_GetArrayItem(cJSON_GetObjectItem(o, "values"), 0);
	TEST_ASSERT_EQUAL_INT(0xB000, cJSON_GetObjectItem(v, "index")->valueint);
	TEST_ASSERT_EQUAL_STRING("00 00 a0 41", cJSON_GetObjectItem(v, "hex")->valuestring);
	TEST_ASSERT_EQUAL_DOUBLE(20.0, cJSON_GetObjectItem(v, "r32")->valuedouble);
	cJSON_Delete(o);

	expect_exit(0, ctl_run("pdo read 0 b000 0 r32"));
	TEST_ASSERT_EQUAL_STRING("B000:00 = 20\n", res.out);
	/* the default configuration has no TPDO on the daemon's side */
	r = ctl_run("pdo request 0 1");
	expect_exit(1, r);
	expect_contains(r->err, "TPDO 1 request on line 0");

	/* nmt stop to node 1: it leaves OPERATIONAL, the monitor sees it */
	bg_start("monitor --line 0 --class nmt --count 1 --duration 20");
	wait_subscribed();
	expect_exit(0, ctl_run("nmt stop 0 1"));
	r = bg_finish(30000);
	expect_exit(0, r);
	expect_contains(r->out, "line 0 nmt   node 1 operational -> stopped");

	/* no more RPDOs now: the daemon's image keeps what is written locally */
	expect_exit(0, ctl_run("pdo write 0 b000 0 r32 7.25"));
	expect_exit(0, ctl_run("pdo read 0 b000 0"));
	TEST_ASSERT_EQUAL_STRING("B000:00 = 00 00 e8 40 (= 1088946176 as u32)\n", res.out);
}

static void test_raw_send_and_dump(void)
{
	start_system();
	int fd = can_open_raw("vcan2");
	TEST_ASSERT_TRUE(fd >= 0);
	ctl_result *r = ctl_run("raw send 2 123#DEADBEEF 321#11.22 7FF#R");
	expect_exit(0, r);
	TEST_ASSERT_EQUAL_STRING("line 2: 3 frames sent\n", r->out);
	uint8_t d[8];
	TEST_ASSERT_EQUAL_INT(4, can_wait_id(fd, 0x123, d, 3000));
	TEST_ASSERT_EQUAL_HEX8_ARRAY(((uint8_t[]){ 0xDE, 0xAD, 0xBE, 0xEF }), d, 4);
	TEST_ASSERT_EQUAL_INT(2, can_wait_id(fd, 0x321, d, 3000));
	TEST_ASSERT_EQUAL_HEX8_ARRAY(((uint8_t[]){ 0x11, 0x22 }), d, 2);

	/* dump with a filter: only 321h comes through */
	bg_start("raw dump 2 321 --count 2 --duration 20");
	wait_subscribed();
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x322, (const uint8_t[]){ 1 }, 1));
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x321, (const uint8_t[]){ 0xA5, 0x5A }, 2));
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x321, (const uint8_t[]){ 0 }, 0));
	r = bg_finish(30000);
	close(fd);
	expect_exit(0, r);
	expect_contains(r->out, "line 2 raw   321#A55A\n");
	expect_contains(r->out, "line 2 raw   321#\n");
	TEST_ASSERT_NULL(strstr(r->out, "322#"));
	expect_contains(r->err, "2 events");
}

static void test_emcy_both_ways(void)
{
	start_system();
	/* the daemon sends: 80h + 127 on vcan0 */
	int fd = can_open_raw("vcan0");
	TEST_ASSERT_TRUE(fd >= 0);
	ctl_result *r = ctl_run("emcy send 0 1000 1 \"01 02 03\"");
	expect_exit(0, r);
	uint8_t d[8];
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd, 0x80 + 127, d, 3000));
	TEST_ASSERT_EQUAL_HEX8_ARRAY(
		((uint8_t[]){ 0x00, 0x10, 0x01, 0x01, 0x02, 0x03, 0x00, 0x00 }), d, 8);
	close(fd);

	/* the daemon receives node 1's EMCY: the monitor prints it */
	bg_start("--json monitor --line 0 --class emcy --count 1 --duration 20");
	wait_subscribed();
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "emcy 0x8130 0x10", NULL, 0, 3000));
	r = bg_finish(30000);
	expect_exit(0, r);
	cJSON *o = cJSON_Parse(r->out);
	TEST_ASSERT_NOT_NULL(o);
	TEST_ASSERT_EQUAL_STRING("emcy", cJSON_GetObjectItem(o, "class")->valuestring);
	TEST_ASSERT_EQUAL_INT(1, cJSON_GetObjectItem(o, "node")->valueint);
	TEST_ASSERT_EQUAL_INT(0x8130, cJSON_GetObjectItem(o, "code")->valueint);
	cJSON_Delete(o);
	r = ctl_run("status 0");
	expect_contains(r->out, "error active");
}

/* Two devices on node-ID 1 of a line without a manager: both answer one
 * SDO request. The daemon says so: a dup-node event (nmt class) naming the
 * node and the object, the node table's flag, a line in status. */
static void test_two_devices_on_one_node_id_reported(void)
{
	start_system();
	char dir[DAEMON_PATH_MAX + 8];
	snprintf(dir, sizeof dir, "%s/twin", dmn.dir);
	TEST_ASSERT_EQUAL_INT(0, mkdir(dir, 0700));
	/* it starts off the bus: its boot-up could not be told from node 1's
	 * heartbeats by cosim_start */
	const char *devices[] = { "etc/devices/sti-pressure.json:1", NULL };
	const char *off_bus[] = { "--silent", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&twin, dir, 0, devices, off_bus));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&twin, "silent off", NULL, 0, 3000));
	expect_exit(0, ctl_run("--json status 0"));
	expect_contains(res.out, "\"duplicate_id\":false");

	bg_start("--json monitor --line 0 --class nmt --duration 6");
	wait_subscribed();
	expect_exit(0, ctl_run("sdo read 0 1 1018 1 u32"));
	ctl_result *r = bg_finish(30000);
	expect_exit(0, r);
	expect_contains(r->out, "\"event\":\"dup-node\"");
	/* one JSON object per line: parse the line of that event */
	const char *ev = strstr(r->out, "\"event\":\"dup-node\"");
	while (ev > r->out && ev[-1] != '\n')
		ev--;
	cJSON *o = cJSON_Parse(ev);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, r->out);
	TEST_ASSERT_EQUAL_INT(1, cJSON_GetObjectItem(o, "node")->valueint);
	TEST_ASSERT_EQUAL_INT(0x1018, cJSON_GetObjectItem(o, "index")->valueint);
	TEST_ASSERT_EQUAL_INT(1, cJSON_GetObjectItem(o, "sub")->valueint);
	TEST_ASSERT_EQUAL_INT(1, cJSON_GetObjectItem(o, "count")->valueint);
	cJSON_Delete(o);

	r = ctl_run("status 0");
	expect_exit(0, r);
	expect_contains(r->out, "TWO DEVICES on node-ID 1");
	expect_exit(0, ctl_run("--json status 0"));
	expect_contains(res.out, "\"duplicate_id\":true");
	cosim_stop(&twin, 3000);
}

static void test_lss_inquire_and_fastscan(void)
{
	start_system();
	expect_exit(0, ctl_run("lss switch 0 config"));
	TEST_ASSERT_EQUAL_STRING("line 0: LSS switch: ok\n", res.out);
	expect_exit(0, ctl_run("lss inquire 0 serial"));
	TEST_ASSERT_EQUAL_STRING("line 0: serial = 123456 (0x0001E240)\n", res.out);
	expect_exit(0, ctl_run("--json lss inquire 0 vendor"));
	expect_contains(res.out, "\"value\":592");
	expect_exit(0, ctl_run("lss inquire 0 node"));
	TEST_ASSERT_EQUAL_STRING("line 0: node = 1 (0x00000001)\n", res.out);
	expect_exit(0, ctl_run("lss switch 0 waiting"));
	/* node 1 is configured: a Fastscan finds nobody */
	ctl_result *r = ctl_run("lss fastscan 0");
	expect_exit(1, r);
	expect_contains(r->err, "no LSS slave answered");
}

/* Exit 4 either way, but the message says who did not
 * answer. Before the fix an LSS service nobody answered printed "the
 * daemon did not answer in time; --timeout MS" although the daemon had
 * answered with the LSS timeout. */
static void test_timeouts_name_who_did_not_answer(void)
{
	start_system();
	/* nobody in LSS configuration mode: the device does not answer */
	expect_exit(0, ctl_run("lss switch 0 waiting"));
	ctl_result *r = ctl_run("lss inquire 0 serial");
	expect_exit(4, r);
	expect_contains(r->err, "the device did not answer");
	TEST_ASSERT_NULL_MESSAGE(strstr(r->err, "the daemon did not answer"), r->err);
	r = ctl_run("--json lss inquire 0 serial");
	expect_exit(4, r);
	expect_contains(r->out, "\"timeout\":\"device\"");
	/* an SDO device timeout says so too */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "sdo silent on", NULL, 0, 3000));
	r = ctl_run("sdo read 0 1 1018 1 u32 --sdo-timeout 300");
	expect_exit(4, r);
	expect_contains(r->err, "the device did not answer on the bus in time");
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "sdo silent off", NULL, 0, 3000));
	/* the daemon itself does not answer (stopped): that is the daemon */
	TEST_ASSERT_EQUAL_INT(0, kill(dmn.pid, SIGSTOP));
	r = ctl_run("--timeout 500 lss inquire 0 serial");
	TEST_ASSERT_EQUAL_INT(0, kill(dmn.pid, SIGCONT));
	expect_exit(4, r);
	expect_contains(r->err, "the daemon did not answer in time");
	r = ctl_run("--timeout 5000 status 0");
	expect_exit(0, r);
}

/* COGW_TEST_ONLY=substring runs only the tests whose name contains it. */
#undef RUN_TEST
#define RUN_TEST(fn)                                            \
	do {                                                    \
		const char *only_ = getenv("COGW_TEST_ONLY");   \
		if (!only_ || strstr(#fn, only_))               \
			UnityDefaultTestRun(fn, #fn, __LINE__); \
	} while (0)

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_help_documents_every_subcommand);
	RUN_TEST(test_usage_errors_exit_2_and_no_daemon_exits_3);
	RUN_TEST(test_status_sdo_types_json_and_aborts);
	RUN_TEST(test_sdo_domain_from_file_and_to_file);
	RUN_TEST(test_nmt_monitor_pdo_and_process_image);
	RUN_TEST(test_raw_send_and_dump);
	RUN_TEST(test_emcy_both_ways);
	RUN_TEST(test_two_devices_on_one_node_id_reported);
	RUN_TEST(test_lss_inquire_and_fastscan);
	RUN_TEST(test_timeouts_name_who_did_not_answer);
	return UNITY_END();
}
