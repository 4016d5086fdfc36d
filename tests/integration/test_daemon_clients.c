/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_daemon_clients.c - several client processes
 * (libcogw) against the real cogwd, with simulated devices (cosim) on the
 * vcan lines:
 *
 *  - three clients at once doing SDO transfers of every size class in every
 *    mode on two lines, data checked byte for byte, correlation ids of the
 *    responses and SDO_DONE events checked;
 *  - four clients subscribed to different event classes on different
 *    lines (NMT/HB/BOOT, EMCY x2, PDO): each gets exactly what it asked for;
 *  - more SDO uploads in flight than a line has large buffers;
 *  - a client killed (SIGKILL) in the middle of a 100 KiB block upload: the
 *    daemon reaps it and serves the next transfer to the same node;
 *  - a client flooding commands while others on the same and on other lines
 *    keep being served (latency printed);
 *  - the embedded default configuration with three concurrent clients:
 *    requests sent == responses received, all correct;
 *  - the release daemon under valgrind: no leak, no error.
 *
 * Clients are fork()ed children; each reports through a pipe ("FAIL ..."
 * lines and figures) and its exit status. The parent never asserts inside
 * a child. Run from the repository root:
 *   make build/san/tests/integration/test_daemon_clients build/san/bin/cogwd \
 *        build/san/bin/cosim build/rel/bin/cogwd
 *   tests/vcan/run -n 3 -- build/san/tests/integration/test_daemon_clients
 * COGW_TEST_ONLY=<part of a test name> runs only the matching tests.
 */
#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <mqueue.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define INSTANCE "itclients"
#define DOMAIN_A 0x2200 /* DOMAIN objects added to copies of the device files */
#define DOMAIN_B 0x2201
#define DOMAIN_MAX (128u * 1024u)
#define BIG_SIZE (100u * 1024u)
#define NODE_PT 1 /* sti-pressure on vcan0 */
#define NODE_IO 2 /* io-generic on vcan1 */
#define CHILDREN_MAX 8

/* The daemon under test: three lines; line 0 consumes the transducer's
 * heartbeat and maps its TPDO 1 (181h, REAL32 pressure) into a local
 * object through RPDO 1, so that PDO events carry the value. */
static const char config_json[] =
	"{\n"
	" \"version\": 1,\n"
	" \"mailbox\": {\"instance\": \"" INSTANCE "\", \"depth\": 64, \"msg_size\": 1024,\n"
	"             \"max_clients\": 16},\n"
	" \"lines\": [\n"
	"  {\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": "
	"127,\n"
	"   \"sdo_timeout_ms\": 10000, \"heartbeat_ms\": 1000,\n"
	"   \"heartbeat_consumers\": [{\"node_id\": 1, \"time_ms\": 10000}],\n"
	"   \"rpdos\": 1,\n"
	"   \"objects\": [{\"index\": \"0x2003\", \"name\": \"pressure of node 1\", \"type\": "
	"\"REAL32\",\n"
	"                \"access\": \"rww\", \"pdo\": true, \"default\": 0.0}],\n"
	"   \"values\": [\n"
	"    {\"index\": \"0x1400\", \"sub\": 1, \"value\": \"0x181\"},\n"
	"    {\"index\": \"0x1400\", \"sub\": 2, \"value\": 254},\n"
	"    {\"index\": \"0x1600\", \"sub\": 0, \"value\": 1},\n"
	"    {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0x20030020\"}]},\n"
	"  {\"name\": \"line1\", \"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": "
	"127,\n"
	"   \"sdo_timeout_ms\": 10000, \"heartbeat_ms\": 1000,\n"
	"   \"heartbeat_consumers\": [{\"node_id\": 2, \"time_ms\": 10000}]},\n"
	"  {\"name\": \"line2\", \"interface\": \"vcan2\", \"bitrate\": 1000000, \"node_id\": "
	"127,\n"
	"   \"heartbeat_ms\": 1000}\n"
	" ]\n"
	"}\n";

static daemon_run dmn;
static cosim_run sim0, sim1;
static const char *instance = INSTANCE; /* the children's daemon instance */

/* ---- small helpers ---------------------------------------------------------------- */

static uint64_t mono_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* Distinct, position-dependent bytes: a shifted or mixed-up transfer (or
 * another client's data) cannot compare equal. */
static void fill_pattern(uint8_t *buf, size_t len, unsigned seed)
{
	for (size_t i = 0; i < len; i++)
		buf[i] = (uint8_t)(seed * 131u + i * 7u + (i >> 8) * 13u + 1u);
}

static const char *mode_name(unsigned m)
{
	static const char *const names[] = { "auto", "expedited", "segmented", "block" };
	return m < 4 ? names[m] : "?";
}

/* Copy of a shipped device file with two extra DOMAIN objects (rw, 128 KiB
 * capacity, empty at start) for the transfer tests. */
static void write_device_copy(const char *src, const char *dst)
{
	FILE *f = fopen(src, "r");
	TEST_ASSERT_NOT_NULL_MESSAGE(f, src);
	static char text[65536];
	size_t n = fread(text, 1, sizeof text - 1, f);
	fclose(f);
	text[n] = '\0';
	cJSON *root = cJSON_Parse(text);
	TEST_ASSERT_NOT_NULL_MESSAGE(root, "device file does not parse");
	cJSON *objects = cJSON_GetObjectItemCaseSensitive(root, "objects");
	TEST_ASSERT_TRUE(cJSON_IsArray(objects));
	const unsigned indexes[2] = { DOMAIN_A, DOMAIN_B };
	for (int i = 0; i < 2; i++) {
		char idx[16];
		snprintf(idx, sizeof idx, "0x%04X", indexes[i]);
		cJSON *o = cJSON_CreateObject();
		cJSON_AddStringToObject(o, "index", idx);
		cJSON_AddStringToObject(o, "name", i ? "test domain B" : "test domain A");
		cJSON_AddStringToObject(o, "type", "DOMAIN");
		cJSON_AddStringToObject(o, "access", "rw");
		cJSON_AddNumberToObject(o, "max_size", DOMAIN_MAX);
		cJSON_AddItemToArray(objects, o);
	}
	char *out = cJSON_Print(root);
	TEST_ASSERT_EQUAL_INT(0, write_text_file(dst, out));
	free(out);
	cJSON_Delete(root);
}

/* Daemon with config_json + the transducer on vcan0 and the I/O module on
 * vcan1, both with the extra DOMAIN objects. */
static void start_system(void)
{
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = config_json,
								    .instance = INSTANCE,
								    .n_lines = 3,
								    .notify = true,
								    .drop_notify = true }));
	char pt[128], io[128];
	snprintf(pt, sizeof pt, "%s/sti-pressure.json", dmn.dir);
	snprintf(io, sizeof io, "%s/io-generic.json", dmn.dir);
	write_device_copy("etc/devices/sti-pressure.json", pt);
	write_device_copy("etc/devices/io-generic.json", io);
	const char *dev0[] = { pt, NULL }, *dev1[] = { io, NULL };
	/* The VM under load can stall a process for over a second: the
	 * devices' SDO servers wait 10 s per frame, like the daemon's SDO
	 * client (lines[].sdo_timeout_ms above), instead of the default 1 s. */
	static const char *const slow_vm[] = { "--sdo-timeout", "10000", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, slow_vm));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim1, dmn.dir, 1, dev1, slow_vm));
}

static int open_client(cogw **h, unsigned event_depth)
{
	cogw_options o = { .instance = instance, .timeout_ms = 30000, .event_depth = event_depth };
	return cogw_open_opts(h, &o);
}

/* ---- child processes ---------------------------------------------------------------- */

/* Parent side of one forked client. */
typedef struct child {
	pid_t pid;
	int to_child, from_child;
	char name[24];
	char out[16384]; /* everything it reported */
	size_t out_len;
	size_t scanned; /* child_expect consumed up to here */
	int status;
	bool reaped;
} child;

/* Child side. */
typedef struct child_ctx {
	int in, out;
	const char *name;
	void *arg;
	char inbuf[256];
	size_t in_len;
} child_ctx;

typedef int (*child_fn)(child_ctx *cx);

static child kids[CHILDREN_MAX];
static size_t n_kids;

static void child_say(child_ctx *cx, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void child_say(child_ctx *cx, const char *fmt, ...)
{
	char line[1024];
	va_list ap;
	va_start(ap, fmt);
	int n = vsnprintf(line, sizeof line - 1, fmt, ap);
	va_end(ap);
	if (n < 0)
		return;
	if ((size_t)n > sizeof line - 2)
		n = (int)sizeof line - 2;
	line[n++] = '\n';
	ssize_t w = write(cx->out, line, (size_t)n);
	(void)w;
}

/* Wait for one line from the parent starting with word. */
static bool child_wait(child_ctx *cx, const char *word, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		char *nl = memchr(cx->inbuf, '\n', cx->in_len);
		if (nl) {
			size_t len = (size_t)(nl - cx->inbuf) + 1;
			bool match = strncmp(cx->inbuf, word, strlen(word)) == 0;
			memmove(cx->inbuf, cx->inbuf + len, cx->in_len - len);
			cx->in_len -= len;
			if (match)
				return true;
			continue;
		}
		uint64_t now = mono_ms();
		struct pollfd p = { .fd = cx->in, .events = POLLIN };
		/* poll at least once, also with timeout 0 (child_told) */
		if (poll(&p, 1, now >= until ? 0 : (int)(until - now)) <= 0) {
			if (mono_ms() >= until)
				return false;
			continue;
		}
		ssize_t n = read(cx->in, cx->inbuf + cx->in_len, sizeof cx->inbuf - cx->in_len);
		if (n <= 0)
			return false; /* parent gone */
		cx->in_len += (size_t)n;
	}
}

/* Has the parent said word (non-blocking)? */
static bool child_told(child_ctx *cx, const char *word)
{
	return child_wait(cx, word, 0);
}

#define CK(cond, ...)                                                                 \
	do {                                                                          \
		if (!(cond)) {                                                        \
			char ck_msg_[768];                                            \
			snprintf(ck_msg_, sizeof ck_msg_, __VA_ARGS__);               \
			child_say(cx, "FAIL %s:%d: %s", cx->name, __LINE__, ck_msg_); \
			goto out;                                                     \
		}                                                                     \
	} while (0)

static child *child_start(const char *name, child_fn fn, void *arg)
{
	TEST_ASSERT_TRUE(n_kids < CHILDREN_MAX);
	int down[2], up[2];
	TEST_ASSERT_EQUAL_INT(0, pipe2(down, O_CLOEXEC));
	TEST_ASSERT_EQUAL_INT(0, pipe2(up, O_CLOEXEC));
	fflush(stdout);
	pid_t pid = fork();
	TEST_ASSERT_TRUE(pid >= 0);
	if (pid == 0) {
		close(down[1]);
		close(up[0]);
		child_ctx cx = { .in = down[0], .out = up[1], .name = name, .arg = arg };
		int rc = fn(&cx);
		/* _exit: no Unity, no atexit handlers of the parent's image */
		_exit(rc == 0 ? 0 : 1);
	}
	close(down[0]);
	close(up[1]);
	child *c = &kids[n_kids++];
	memset(c, 0, sizeof *c);
	c->pid = pid;
	c->to_child = down[1];
	c->from_child = up[0];
	snprintf(c->name, sizeof c->name, "%s", name);
	fcntl(c->from_child, F_SETFL, O_NONBLOCK);
	return c;
}

/* Read what is there (or wait up to timeout_ms for something). Returns
 * false at EOF. */
static bool child_pump(child *c, int timeout_ms)
{
	struct pollfd p = { .fd = c->from_child, .events = POLLIN };
	if (c->from_child < 0)
		return false;
	if (poll(&p, 1, timeout_ms) <= 0)
		return true;
	char buf[2048];
	ssize_t n = read(c->from_child, buf, sizeof buf);
	if (n <= 0) {
		if (n < 0 && errno == EAGAIN)
			return true;
		close(c->from_child);
		c->from_child = -1;
		return false;
	}
	size_t room = sizeof c->out - 1 - c->out_len;
	size_t take = (size_t)n < room ? (size_t)n : room;
	memcpy(c->out + c->out_len, buf, take);
	c->out_len += take;
	c->out[c->out_len] = '\0';
	return true;
}

/* Wait until the child has reported a line starting with word. */
static bool child_expect(child *c, const char *word, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		char *line = c->out + c->scanned;
		char *nl;
		while ((nl = strchr(line, '\n')) != NULL) {
			c->scanned = (size_t)(nl + 1 - c->out);
			if (strncmp(line, word, strlen(word)) == 0)
				return true;
			line = nl + 1;
		}
		uint64_t now = mono_ms();
		if (now >= until || !child_pump(c, (int)(until - now > 100 ? 100 : until - now)))
			return false;
	}
}

static void child_send(child *c, const char *word)
{
	char line[64];
	int n = snprintf(line, sizeof line, "%s\n", word);
	ssize_t w = write(c->to_child, line, (size_t)n);
	(void)w;
}

/* Wait for the exit, collect the rest of the output, print it (prefixed)
 * and return true if it exited 0 without a FAIL line. */
static bool child_join(child *c, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	while (!c->reaped) {
		if (proc_exited(c->pid, &c->status)) {
			c->reaped = true;
			break;
		}
		if (mono_ms() >= until) {
			printf("%s: still running after %d ms: killed\n", c->name, timeout_ms);
			kill(c->pid, SIGKILL);
			waitpid(c->pid, &c->status, 0);
			c->reaped = true;
			break;
		}
		child_pump(c, 50);
	}
	while (child_pump(c, 0) && c->from_child >= 0)
		;
	for (char *line = c->out; *line;) {
		char *nl = strchr(line, '\n');
		if (nl)
			*nl = '\0';
		printf("  [%s] %s\n", c->name, line);
		if (!nl)
			break;
		*nl = '\n';
		line = nl + 1;
	}
	bool ok = WIFEXITED(c->status) && WEXITSTATUS(c->status) == 0 && !strstr(c->out, "FAIL");
	if (!ok)
		printf("%s: exit status 0x%x\n", c->name, c->status);
	return ok;
}

static void children_reset(void)
{
	for (size_t i = 0; i < n_kids; i++) {
		child *c = &kids[i];
		if (Unity.CurrentTestFailed && !c->reaped && c->pid > 0) {
			/* what it said so far, and where it hangs */
			kill(c->pid, SIGKILL);
			child_join(c, 5000);
		}
		if (!c->reaped && c->pid > 0) {
			kill(c->pid, SIGKILL);
			waitpid(c->pid, &c->status, 0);
			c->reaped = true;
		}
		if (c->to_child >= 0)
			close(c->to_child);
		if (c->from_child >= 0)
			close(c->from_child);
		c->to_child = c->from_child = -1;
	}
	n_kids = 0;
}

/* ---- Unity fixtures ------------------------------------------------------------------ */

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim0, 0, sizeof sim0);
	memset(&sim1, 0, sizeof sim1);
	instance = INSTANCE;
	n_kids = 0;
}

void tearDown(void)
{
	children_reset();
	if (Unity.CurrentTestFailed) {
		if (sim0.pid > 0)
			proc_dump_log(sim0.log_path, 15);
		if (sim1.pid > 0)
			proc_dump_log(sim1.log_path, 15);
		if (dmn.pid > 0)
			proc_dump_log(dmn.log_path, 30);
	}
	cosim_stop(&sim0, 5000);
	cosim_stop(&sim1, 5000);
	daemon_cleanup(&dmn);
	/* a killed client's queues, or a failed run's: never leave any */
	daemon_unlink_queues(INSTANCE);
	daemon_unlink_queues("main");
}

/* Stop everything and check that nothing is left: clean exits, no queue of
 * the instance (daemon command queues and client queues alike). */
static void stop_system_and_check(void)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, cosim_stop(&sim0, 5000), "cosim on vcan0: exit status");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, cosim_stop(&sim1, 5000), "cosim on vcan1: exit status");
	int st = daemon_stop(&dmn, 20000);
	TEST_ASSERT_TRUE_MESSAGE(st != -1 && WIFEXITED(st) && WEXITSTATUS(st) == 0,
				 "cogwd did not exit with status 0 on SIGTERM");
	char report[512];
	int left = daemon_leftovers(dmn.instance, NULL, 0, report, sizeof report);
	if (left)
		printf("leftovers: %s\n", report);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, left, "queues left behind");
}

/* ---- asynchronous SDO with its SDO_DONE event ------------------------------------------ */

typedef struct sdo_outcome {
	int status;
	uint32_t abort;
	uint8_t mode_used;       /* from the SDO_DONE event */
	uint32_t size;           /* from the SDO_DONE event */
	size_t len;              /* response data */
	unsigned foreign_events; /* SDO_DONE of other clients' transfers */
} sdo_outcome;

/*
 * One SDO transfer through cogw_send_async(); waits for both its response
 * and its SDO_DONE event (the client subscribed MBX_EVC_SDO on the line).
 * Checks that the response and the event carry this request's corr. The
 * caller owns `index` on that line exclusively, so an SDO_DONE for another
 * object is another client's (counted), and one for ours must be ours.
 * Returns 0, or -1 with a reason in err.
 */
static int sdo_async(cogw *h, unsigned line, uint8_t node, uint16_t index, bool upload,
		     uint8_t mode, const uint8_t *data, size_t len, uint8_t *out, size_t cap,
		     sdo_outcome *res, char *err, size_t errcap)
{
	memset(res, 0, sizeof *res);
	size_t plen = sizeof(mbx_sdo_req) + (upload ? 0 : len);
	uint8_t *payload = malloc(plen ? plen : 1);
	if (!payload)
		return snprintf(err, errcap, "out of memory"), -1;
	mbx_sdo_req rq = { .node = node, .mode = mode, .index = index, .sub = 0 };
	memcpy(payload, &rq, sizeof rq);
	if (!upload && len)
		memcpy(payload + sizeof rq, data, len);
	uint64_t corr = 0;
	int rc = cogw_send_async(h, line, upload ? MBX_CMD_SDO_UPLOAD : MBX_CMD_SDO_DOWNLOAD,
				 payload, plen, &corr);
	free(payload);
	if (rc < 0)
		return snprintf(err, errcap, "send_async: %s", cogw_strerror(rc)), -1;

	bool got_resp = false, got_event = false;
	uint64_t until = mono_ms() + 120000;
	while (!(got_resp && got_event)) {
		int left = (int)(until > mono_ms() ? until - mono_ms() : 0);
		cogw_msg m;
		rc = cogw_recv(h, &m, left);
		if (rc == COGW_E_AGAIN)
			return snprintf(err, errcap, "%04X %s: no %s within 120 s", index,
					upload ? "upload" : "download",
					got_resp ? "SDO_DONE" : "response"),
			       -1;
		if (rc < 0)
			return snprintf(err, errcap, "cogw_recv: %s", cogw_strerror(rc)), -1;
		int bad = 0;
		if (m.kind == MBX_KIND_RESPONSE) {
			if (m.corr != corr || got_resp ||
			    m.code != (upload ? MBX_CMD_SDO_UPLOAD : MBX_CMD_SDO_DOWNLOAD) ||
			    m.line != line) {
				snprintf(err, errcap,
					 "unexpected response corr %llu code %04x line %u (mine "
					 "%llu)",
					 (unsigned long long)m.corr, m.code, m.line,
					 (unsigned long long)corr);
				bad = 1;
			} else {
				got_resp = true;
				res->status = m.status;
				res->abort = m.abort;
				res->len = m.len;
				if (upload && m.status == 0) {
					if (m.len > cap) {
						snprintf(err, errcap, "upload of %zu bytes > %zu",
							 m.len, cap);
						bad = 1;
					} else {
						memcpy(out, m.data, m.len);
					}
				}
			}
		} else if (m.code == MBX_EV_SDO_DONE && m.len >= sizeof(mbx_ev_sdo_done)) {
			mbx_ev_sdo_done ev;
			memcpy(&ev, m.data, sizeof ev);
			if (m.line == line && ev.index == index && ev.node == node) {
				if (m.corr != corr || got_event || ev.upload != upload) {
					snprintf(err, errcap,
						 "SDO_DONE of my object %04X with corr %llu upload "
						 "%u (mine %llu)",
						 index, (unsigned long long)m.corr, ev.upload,
						 (unsigned long long)corr);
					bad = 1;
				}
				got_event = true;
				res->mode_used = ev.mode;
				res->size = ev.size;
				if (ev.abort != res->abort && got_resp) {
					snprintf(err, errcap, "SDO_DONE abort %08x, response %08x",
						 ev.abort, res->abort);
					bad = 1;
				}
			} else {
				res->foreign_events++;
			}
		} else {
			snprintf(err, errcap, "unsubscribed event %s (%04x) on line %u",
				 mbx_event_to_string(m.code), m.code, m.line);
			bad = 1;
		}
		cogw_msg_release(&m);
		if (bad)
			return -1;
	}
	return 0;
}

/* ---- 1. three clients, every size class and mode, two lines ----------------------------- */

typedef struct xfer_plan {
	unsigned id; /* seeds the data */
	unsigned n_targets;
	struct {
		unsigned line;
		uint8_t node;
		uint16_t index;
	} targets[2];
} xfer_plan;

static const size_t size_classes[] = { 0, 1, 3, 4, 5, 7, 8, 100, 889, 890, 3000, BIG_SIZE };

static int child_transfers(child_ctx *cx)
{
	const xfer_plan *plan = cx->arg;
	cogw *h = NULL;
	uint8_t *data = malloc(BIG_SIZE), *back = malloc(DOMAIN_MAX);
	int rc = -1;
	char err[256];
	unsigned transfers = 0, foreign = 0, k = 0;
	uint64_t bytes = 0, t0 = mono_us();
	CK(data && back, "out of memory");
	int open_rc_ = open_client(&h, 64);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	for (unsigned t = 0; t < plan->n_targets; t++) {
		int s = cogw_subscribe(h, plan->targets[t].line, MBX_EVC_SDO, NULL, 0, 0);
		CK(s == 0, "subscribe SDO on line %u: %s", plan->targets[t].line, cogw_strerror(s));
	}
	child_say(cx, "ready");
	CK(child_wait(cx, "go", 60000), "no go");

	for (size_t si = 0; si < sizeof size_classes / sizeof size_classes[0]; si++) {
		size_t len = size_classes[si];
		static const uint8_t modes[] = { 1, 2, 3 }; /* expedited, segmented, block */
		for (size_t mi = 0; mi < 3; mi++) {
			uint8_t mode = modes[mi];
			if (mode == 1 && (len < 1 || len > 4))
				continue; /* expedited carries 1..4 bytes only */
			if (len == BIG_SIZE && mode != 3)
				continue; /* 100 KiB segmented takes ~20 s in the VM: block only */
			/* alternate the targets (lines) and the upload mode */
			const unsigned t = k % plan->n_targets;
			const unsigned line = plan->targets[t].line;
			const uint8_t node = plan->targets[t].node;
			const uint16_t index = plan->targets[t].index;
			const uint8_t up_mode = len == BIG_SIZE || (k / plan->n_targets) % 2 ? 3
											     : 2;
			k++;
			fill_pattern(data, len, plan->id * 1000u + k);
			sdo_outcome r;
			uint64_t a = mono_us();
			CK(sdo_async(h, line, node, index, false, mode, data, len, NULL, 0, &r, err,
				     sizeof err) == 0,
			   "download %zu B %s line %u: %s", len, mode_name(mode), line, err);
			CK(r.status == 0, "download %zu B %s to %u:%04X: %s abort %08x", len,
			   mode_name(mode), node, index, cogw_strerror(r.status), r.abort);
			CK(r.size == len, "download %zu B: SDO_DONE says %u bytes", len, r.size);
			uint8_t want = mode == 1 || (len >= 1 && len <= 4 && mode == 0) ? 1 : mode;
			CK(r.mode_used == want, "download %zu B asked %s, used %s", len,
			   mode_name(mode), mode_name(r.mode_used));
			foreign += r.foreign_events;
			uint64_t b = mono_us();

			memset(back, 0xEE, len + 16 < DOMAIN_MAX ? len + 16 : DOMAIN_MAX);
			CK(sdo_async(h, line, node, index, true, up_mode, NULL, 0, back, DOMAIN_MAX,
				     &r, err, sizeof err) == 0,
			   "upload %zu B %s line %u: %s", len, mode_name(up_mode), line, err);
			CK(r.status == 0, "upload %zu B %s from %u:%04X: %s abort %08x", len,
			   mode_name(up_mode), node, index, cogw_strerror(r.status), r.abort);
			CK(r.len == len, "upload returned %zu bytes, wrote %zu", r.len, len);
			CK(len == 0 || memcmp(back, data, len) == 0,
			   "upload of %zu B differs from download", len);
			/* a block upload may switch to segmented/expedited below the
			 * protocol switch threshold (CiA 301); above it, it is block */
			if (up_mode == 3 && len >= 256)
				CK(r.mode_used == 3, "upload %zu B asked block, used %s", len,
				   mode_name(r.mode_used));
			if (up_mode == 2 && len > 4)
				CK(r.mode_used == 2, "upload %zu B asked segmented, used %s", len,
				   mode_name(r.mode_used));
			foreign += r.foreign_events;
			uint64_t c = mono_us();
			transfers += 2;
			bytes += 2 * len;
			if (len >= 3000)
				child_say(cx,
					  "line %u %6zu B: download %-9s %7.1f ms, upload %-9s "
					  "%7.1f ms",
					  line, len, mode_name(mode), (double)(b - a) / 1000.0,
					  mode_name(r.mode_used), (double)(c - b) / 1000.0);
		}
	}
	cogw_stats st;
	cogw_get_stats(h, &st);
	CK(st.stray_responses == 0, "%llu stray responses", (unsigned long long)st.stray_responses);
	CK(st.async_dropped == 0 && st.overflow_flags == 0,
	   "async dropped %llu, overflow flags %llu", (unsigned long long)st.async_dropped,
	   (unsigned long long)st.overflow_flags);
	child_say(cx,
		  "%u transfers, %llu bytes in %.1f s; %u SDO_DONE events of other clients seen",
		  transfers, (unsigned long long)bytes, (double)(mono_us() - t0) / 1e6, foreign);
	rc = 0;
out:
	cogw_close(h);
	free(data);
	free(back);
	return rc;
}

static void test_three_clients_transfer_every_size_and_mode_on_two_lines(void)
{
	start_system();
	/* A owns 2200h on line 0, B owns 2200h on line 1, C owns 2201h on
	 * both: every line has two clients transferring at once. */
	static const xfer_plan plans[3] = {
		{ .id = 1, .n_targets = 1, .targets = { { 0, NODE_PT, DOMAIN_A } } },
		{ .id = 2, .n_targets = 1, .targets = { { 1, NODE_IO, DOMAIN_A } } },
		{ .id = 3,
		  .n_targets = 2,
		  .targets = { { 0, NODE_PT, DOMAIN_B }, { 1, NODE_IO, DOMAIN_B } } },
	};
	child *c[3];
	for (int i = 0; i < 3; i++) {
		char name[24];
		snprintf(name, sizeof name, "xfer-%c", 'A' + i);
		c[i] = child_start(name, child_transfers, (void *)&plans[i]);
	}
	for (int i = 0; i < 3; i++)
		TEST_ASSERT_TRUE_MESSAGE(child_expect(c[i], "ready", 30000), "client not ready");
	uint64_t t0 = mono_ms();
	for (int i = 0; i < 3; i++)
		child_send(c[i], "go");
	bool ok = true;
	for (int i = 0; i < 3; i++)
		ok &= child_join(c[i], 480000);
	printf("three clients done in %.1f s\n", (double)(mono_ms() - t0) / 1000.0);
	TEST_ASSERT_TRUE_MESSAGE(ok, "a transfer client failed (see its lines above)");
	stop_system_and_check();
}

/* ---- 1b. event classes reach exactly their subscribers ------------------------------- */

typedef struct event_count {
	unsigned total, nmt, hb, boot, emcy, pdo;
} event_count;

/* Receive events for up to wait_ms; each must come from `line` and be of a
 * class in `classes` (anything else is a FAIL with the reason in err).
 * Calls on_event for each, which may set *done. */
typedef bool (*event_check_fn)(child_ctx *cx, const cogw_msg *m, event_count *n, char *err,
			       size_t cap);

static int receive_events(child_ctx *cx, cogw *h, unsigned line, uint32_t classes, event_count *n,
			  event_check_fn check, const char *until_word, int wait_ms, char *err,
			  size_t cap)
{
	uint64_t until = mono_ms() + (uint64_t)wait_ms;
	while (mono_ms() < until) {
		if (until_word && child_told(cx, until_word))
			return 0;
		cogw_msg m;
		int rc = cogw_recv(h, &m, 100);
		if (rc == COGW_E_AGAIN)
			continue;
		if (rc < 0)
			return snprintf(err, cap, "cogw_recv: %s", cogw_strerror(rc)), -1;
		bool ok = true;
		uint32_t cls = mbx_event_class_of(m.code);
		if (m.kind != MBX_KIND_EVENT) {
			ok = false;
			snprintf(err, cap, "a response (code %04x corr %llu) nobody asked for",
				 m.code, (unsigned long long)m.corr);
		} else if (m.line != line || !(cls & classes)) {
			ok = false;
			snprintf(err, cap, "event %s on line %u: not subscribed",
				 mbx_event_to_string(m.code), m.line);
		} else {
			n->total++;
			n->nmt += m.code == MBX_EV_NMT_STATE;
			n->hb += m.code == MBX_EV_HB_STARTED || m.code == MBX_EV_HB_LOST;
			n->boot += m.code == MBX_EV_BOOTUP;
			n->emcy += m.code == MBX_EV_EMCY;
			n->pdo += m.code == MBX_EV_PDO;
			ok = check(cx, &m, n, err, cap);
		}
		cogw_msg_release(&m);
		if (!ok)
			return -1;
	}
	return until_word ? (snprintf(err, cap, "no '%s' from the parent", until_word), -1) : 0;
}

/* A: line 0 NMT + HB + BOOT. Sees node 1 go operational (C starts it),
 * then resets node 1 itself and sees its boot-up. */
static bool a_saw_operational, a_saw_bootup;
static bool check_a(child_ctx *cx, const cogw_msg *m, event_count *n, char *err, size_t cap)
{
	(void)n;
	mbx_ev_node ev;
	if (m->len != sizeof ev)
		return snprintf(err, cap, "node event of %zu bytes", m->len), false;
	memcpy(&ev, m->data, sizeof ev);
	if (m->corr != 0)
		return snprintf(err, cap, "node event with corr %llu", (unsigned long long)m->corr),
		       false;
	if (m->code == MBX_EV_NMT_STATE && ev.node == NODE_PT && ev.state == 5)
		a_saw_operational = true;
	if (m->code == MBX_EV_BOOTUP && ev.node == NODE_PT && !a_saw_bootup) {
		a_saw_bootup = true;
		child_say(cx, "bootup");
	}
	return true;
}

static int child_events_a(child_ctx *cx)
{
	cogw *h = NULL;
	int rc = -1;
	char err[256];
	event_count n = { 0 };
	int open_rc_ = open_client(&h, 64);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	int s = cogw_subscribe(h, 0, MBX_EVC_NMT | MBX_EVC_HB | MBX_EVC_BOOT, NULL, 0, 0);
	CK(s == 0, "subscribe: %s", cogw_strerror(s));
	child_say(cx, "ready");
	CK(receive_events(cx, h, 0, MBX_EVC_NMT | MBX_EVC_HB | MBX_EVC_BOOT, &n, check_a, "go",
			  120000, err, sizeof err) == 0,
	   "%s", err);
	CK(a_saw_operational, "no NMT_STATE operational of node 1 (C started it)");
	s = cogw_nmt(h, 0, 0x81, NODE_PT, 0); /* reset node */
	CK(s == 0, "NMT reset node: %s", cogw_strerror(s));
	CK(receive_events(cx, h, 0, MBX_EVC_NMT | MBX_EVC_HB | MBX_EVC_BOOT, &n, check_a, "finish",
			  120000, err, sizeof err) == 0,
	   "%s", err);
	CK(a_saw_bootup, "no BOOTUP of node 1 after the reset");
	child_say(cx, "events: %u (nmt %u, hb %u, boot %u)", n.total, n.nmt, n.hb, n.boot);
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

/* B: line 1 EMCY (and D: line 0 EMCY). */
static uint16_t emcy_expected_code;
static uint8_t emcy_expected_node;
static bool emcy_seen;
static bool check_emcy(child_ctx *cx, const cogw_msg *m, event_count *n, char *err, size_t cap)
{
	(void)n;
	mbx_ev_emcy ev;
	if (m->len != sizeof ev)
		return snprintf(err, cap, "EMCY event of %zu bytes", m->len), false;
	memcpy(&ev, m->data, sizeof ev);
	if (ev.code == 0)
		return true; /* an error reset is allowed */
	if (ev.code != emcy_expected_code || ev.node != emcy_expected_node)
		return snprintf(err, cap, "EMCY %04X from node %u, expected %04X from node %u",
				ev.code, ev.node, emcy_expected_code, emcy_expected_node),
		       false;
	if (!(ev.reg & 0x01))
		return snprintf(err, cap, "EMCY error register %02X without bit 0", ev.reg), false;
	if (!emcy_seen)
		child_say(cx, "emcy");
	emcy_seen = true;
	return true;
}

typedef struct emcy_plan {
	unsigned line;
	uint8_t node;
	uint16_t code;
} emcy_plan;

static int child_events_emcy(child_ctx *cx)
{
	const emcy_plan *p = cx->arg;
	cogw *h = NULL;
	int rc = -1;
	char err[256];
	event_count n = { 0 };
	emcy_expected_code = p->code;
	emcy_expected_node = p->node;
	int open_rc_ = open_client(&h, 64);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	int s = cogw_subscribe(h, p->line, MBX_EVC_EMCY, NULL, 0, 0);
	CK(s == 0, "subscribe: %s", cogw_strerror(s));
	child_say(cx, "ready");
	CK(receive_events(cx, h, p->line, MBX_EVC_EMCY, &n, check_emcy, "finish", 180000, err,
			  sizeof err) == 0,
	   "%s", err);
	CK(emcy_seen, "no EMCY %04X from node %u on line %u", p->code, p->node, p->line);
	child_say(cx, "events: %u (emcy %u)", n.total, n.emcy);
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

/* C: line 0 PDO. Starts node 1 over the mailbox; its TPDO 1 carries the
 * REAL32 pressure, held at 25.0 by the parent (cosim "pressure 25"). */
static unsigned c_pdos_ok;
static bool check_c(child_ctx *cx, const cogw_msg *m, event_count *n, char *err, size_t cap)
{
	(void)n;
	mbx_ev_pdo head;
	mbx_pdo_value v;
	if (m->len != sizeof head + sizeof v)
		return snprintf(err, cap, "PDO event of %zu bytes (one value expected)", m->len),
		       false;
	memcpy(&head, m->data, sizeof head);
	memcpy(&v, m->data + sizeof head, sizeof v);
	if (head.pdo != 1 || head.n != 1 || v.index != 0x2003 || v.sub != 0 || v.len != 4)
		return snprintf(err, cap, "PDO %u n %u value %04X:%02X len %u", head.pdo, head.n,
				v.index, v.sub, v.len),
		       false;
	float f;
	memcpy(&f, v.data, sizeof f);
	if (f != 25.0f)
		return snprintf(err, cap, "pressure %g, expected 25", (double)f), false;
	if (++c_pdos_ok == 3)
		child_say(cx, "pdos");
	return true;
}

static int child_events_c(child_ctx *cx)
{
	cogw *h = NULL;
	int rc = -1;
	char err[256];
	event_count n = { 0 };
	int open_rc_ = open_client(&h, 64);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	int s = cogw_subscribe(h, 0, MBX_EVC_PDO, NULL, 0, 0);
	CK(s == 0, "subscribe: %s", cogw_strerror(s));
	child_say(cx, "ready");
	CK(child_wait(cx, "go", 60000), "no go");
	/* RPDOs run only in OPERATIONAL (CiA 301): start the daemon's own node
	 * on line 0 (applied locally), then the transducer */
	s = cogw_nmt(h, 0, 0x01, 127, 0);
	CK(s == 0, "NMT start of our own node 127: %s", cogw_strerror(s));
	s = cogw_nmt(h, 0, 0x01, NODE_PT, 0);
	CK(s == 0, "NMT start of node 1: %s", cogw_strerror(s));
	CK(receive_events(cx, h, 0, MBX_EVC_PDO, &n, check_c, "finish", 180000, err, sizeof err) ==
		   0,
	   "%s", err);
	CK(c_pdos_ok >= 3, "only %u PDO events with the pressure", c_pdos_ok);
	child_say(cx, "events: %u (pdo %u)", n.total, n.pdo);
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

static void test_event_classes_reach_exactly_their_subscribers(void)
{
	start_system();
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim0, "pressure 25", NULL, 0, 5000));
	static const emcy_plan b_plan = { .line = 1, .node = NODE_IO, .code = 0x1234 };
	static const emcy_plan d_plan = { .line = 0, .node = NODE_PT, .code = 0x5678 };
	child *a = child_start("events-A", child_events_a, NULL);
	child *b = child_start("events-B", child_events_emcy, (void *)&b_plan);
	child *c = child_start("events-C", child_events_c, NULL);
	child *d = child_start("events-D", child_events_emcy, (void *)&d_plan);
	child *all[4] = { a, b, c, d };
	for (int i = 0; i < 4; i++)
		TEST_ASSERT_TRUE_MESSAGE(child_expect(all[i], "ready", 30000), "client not ready");

	/* C starts node 1 and sees its pressure PDOs (A sees it go operational) */
	child_send(c, "go");
	TEST_ASSERT_TRUE_MESSAGE(child_expect(c, "pdos", 60000), "C got no pressure PDOs");
	/* EMCY on both lines: B (line 1) and D (line 0) each get only their own */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim1, "emcy 0x1234", NULL, 0, 5000));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim0, "emcy 0x5678", NULL, 0, 5000));
	TEST_ASSERT_TRUE_MESSAGE(child_expect(b, "emcy", 30000), "B got no EMCY");
	TEST_ASSERT_TRUE_MESSAGE(child_expect(d, "emcy", 30000), "D got no EMCY");
	/* A resets node 1 and sees its boot-up */
	child_send(a, "go");
	TEST_ASSERT_TRUE_MESSAGE(child_expect(a, "bootup", 60000), "A got no boot-up");
	/* the same EMCYs again, after the reset: still only to B and D */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim1, "emcy 0x1234", NULL, 0, 5000));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim0, "emcy 0x5678", NULL, 0, 5000));
	/* An observation window for misrouted events, not a synchronisation:
	 * anything unsubscribed that arrives meanwhile fails its client. */
	sleep_ms(2000);
	bool ok = true;
	for (int i = 0; i < 4; i++)
		child_send(all[i], "finish");
	for (int i = 0; i < 4; i++)
		ok &= child_join(all[i], 60000);
	TEST_ASSERT_TRUE_MESSAGE(ok, "an event client failed (see its lines above)");
	stop_system_and_check();
}

/* ---- 1c. more uploads in flight than the line has large buffers ------------------------- */

/* A line keeps LINE_BIG_SLOTS (4) upload buffers of max_transfer bytes;
 * further uploads in flight use small inline slots. Line 0: two clients x 4
 * asynchronous uploads, line 1: one client x 6, three rounds, so that the
 * small slots are used, released and used again: every answer must carry
 * the right data. (All transfers to one node share one SDO client channel
 * whose queue holds 8 requests: more in flight are answered BUSY, by
 * design, so the test stays at 8.) */
static int child_many_uploads(child_ctx *cx)
{
	const unsigned line = (unsigned)(uintptr_t)cx->arg;
	const uint8_t node = line == 0 ? NODE_PT : NODE_IO;
	const char *want = line == 0 ? "STI-SIM" : "IO-SIM";
	const unsigned n = line == 0 ? 4 : 6; /* in flight per client */
	cogw *h = NULL;
	int rc = -1;
	unsigned ok = 0;
	int open_rc_ = open_client(&h, 0);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	CK(cogw_ping(h, line, 0) == 0, "ping");
	child_say(cx, "ready");
	CK(child_wait(cx, "go", 60000), "no go");
	for (unsigned round = 0; round < 3; round++) {
		uint64_t corr[6];
		bool got[6] = { false };
		mbx_sdo_req rq = { .node = node, .index = 0x1008, .sub = 0 };
		for (unsigned i = 0; i < n; i++) {
			int s = cogw_send_async(h, line, MBX_CMD_SDO_UPLOAD, &rq, sizeof rq,
						&corr[i]);
			CK(s == 0, "send_async: %s", cogw_strerror(s));
		}
		/* n responses. docs/mailbox.md also promises the requester its
		 * SDO_DONE "whatever your subscription"; the daemon sends it to
		 * SDO subscribers only (reported): tolerated, not required. */
		for (unsigned left = n; left;) {
			cogw_msg m;
			int s = cogw_recv(h, &m, 60000);
			CK(s == 0, "round %u: %s with %u answers missing", round, cogw_strerror(s),
			   left);
			unsigned i = 0;
			while (i < n && corr[i] != m.corr)
				i++;
			bool own_done = m.kind == MBX_KIND_EVENT && m.code == MBX_EV_SDO_DONE &&
					i < n;
			bool good = own_done || (m.kind == MBX_KIND_RESPONSE && i < n && !got[i] &&
						 m.status == 0 && m.len == strlen(want) &&
						 memcmp(m.data, want, m.len) == 0);
			char what[160];
			snprintf(what, sizeof what,
				 "kind %u code %04x corr %llu status %s abort %08x len %zu", m.kind,
				 m.code, (unsigned long long)m.corr, cogw_strerror(m.status),
				 m.abort, m.len);
			cogw_msg_release(&m);
			CK(good, "round %u: upload of 1008h: %s", round, what);
			if (own_done)
				continue;
			got[i] = true;
			left--;
			ok++;
		}
	}
	child_say(cx, "%u uploads, all correct", ok);
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

static void test_uploads_in_flight_beyond_the_large_buffers(void)
{
	start_system();
	child *c[3];
	/* two clients on line 0 (8 uploads in flight), one on line 1 (6) */
	static const unsigned lines[3] = { 0, 0, 1 };
	for (int i = 0; i < 3; i++) {
		char name[24];
		snprintf(name, sizeof name, "uploads-%d", i);
		c[i] = child_start(name, child_many_uploads, (void *)(uintptr_t)lines[i]);
	}
	for (int i = 0; i < 3; i++)
		TEST_ASSERT_TRUE_MESSAGE(child_expect(c[i], "ready", 30000), "client not ready");
	for (int i = 0; i < 3; i++)
		child_send(c[i], "go");
	bool ok = true;
	for (int i = 0; i < 3; i++)
		ok &= child_join(c[i], 300000);
	TEST_ASSERT_TRUE_MESSAGE(ok, "a client failed (see its lines above)");
	stop_system_and_check();
}

/* ---- 2. a client killed during a 100 KiB block upload --------------------------------- */

#define KILL_SEED 77u

static int child_victim(child_ctx *cx)
{
	cogw *h = NULL;
	int rc = -1;
	uint32_t abort = 0;
	uint8_t *data = malloc(BIG_SIZE), *back = malloc(DOMAIN_MAX);
	CK(data && back, "out of memory");
	int open_rc_ = open_client(&h, 0);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	child_say(cx, "ready");
	CK(child_wait(cx, "go", 60000), "no go");
	fill_pattern(data, BIG_SIZE, KILL_SEED);
	cogw_sdo_opts block = { .mode = 3 };
	int s = cogw_sdo_write_ex(h, 0, NODE_PT, DOMAIN_A, 0, &block, data, BIG_SIZE, 120000,
				  &abort);
	CK(s == 0, "download: %s abort %08x", cogw_strerror(s), abort);
	child_say(cx, "uploading");
	size_t len = 0;
	s = cogw_sdo_read_ex(h, 0, NODE_PT, DOMAIN_A, 0, &block, back, DOMAIN_MAX, &len, 120000,
			     &abort);
	child_say(cx, "FAIL the upload finished (%d, %zu bytes) before the kill", s, len);
out:
	cogw_close(h);
	free(data);
	free(back);
	return rc;
}

static int count_client_queues(const char *inst, pid_t pid, bool unlink_them)
{
	char prefix[96];
	snprintf(prefix, sizeof prefix, "cogw.%s.c%d.", inst, (int)pid);
	DIR *dir = opendir("/dev/mqueue");
	if (!dir)
		return -1;
	int n = 0;
	struct dirent *e;
	while ((e = readdir(dir)) != NULL) {
		if (strncmp(e->d_name, prefix, strlen(prefix)) != 0)
			continue;
		n++;
		if (unlink_them) {
			char name[300];
			snprintf(name, sizeof name, "/%s", e->d_name);
			mq_unlink(name);
		}
	}
	closedir(dir);
	return n;
}

static void test_killed_client_is_reaped_and_others_are_served(void)
{
	start_system();
	int can = can_open_raw("vcan0");
	TEST_ASSERT_TRUE(can >= 0);
	/* fork before this process has a libcogw handle (and its thread):
	 * ASan's allocator locks are not fork-safe */
	child *v = child_start("victim", child_victim, NULL);
	TEST_ASSERT_TRUE_MESSAGE(child_expect(v, "ready", 30000), "victim not ready");
	cogw *h = NULL;
	TEST_ASSERT_EQUAL_INT(0, open_client(&h, 0));
	mbx_stats_wire st0, st;
	TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(h, 0, &st0, 0));
	TEST_ASSERT_EQUAL_UINT32(1,
				 st0.clients); /* this process; the victim registers on first use */
	child_send(v, "go");
	bool ready = child_expect(v, "uploading", 120000);
	if (!ready)
		child_join(v, 1000);
	TEST_ASSERT_TRUE_MESSAGE(ready, "the victim's download did not complete");
	TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(h, 0, &st, 0));
	TEST_ASSERT_EQUAL_UINT32(2, st.clients);
	/* wait until the upload streams (block segments from node 1 on 581h),
	 * so that the kill lands in the middle of it */
	struct can_frame f;
	while (recv(can, &f, sizeof f, MSG_DONTWAIT) > 0)
		; /* the download's frames */
	int segments = 0;
	while (segments < 40 && can_wait_id(can, 0x580 + NODE_PT, NULL, 20000) >= 0)
		segments++;
	TEST_ASSERT_EQUAL_INT_MESSAGE(40, segments, "the block upload did not start");
	uint64_t killed_at = mono_ms();
	kill(v->pid, SIGKILL);
	waitpid(v->pid, &v->status, 0); /* a zombie would still look alive */
	v->reaped = true;
	TEST_ASSERT_TRUE(WIFSIGNALED(v->status) && WTERMSIG(v->status) == SIGKILL);
	TEST_ASSERT_NULL_MESSAGE(strstr(v->out, "FAIL"), v->out);

	/* the line reaps it (process gone) within its 1 s liveness check */
	bool reaped = false;
	while (!reaped && mono_ms() - killed_at < 15000) {
		TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(h, 0, &st, 0));
		reaped = st.clients == 1 && st.clients_reaped >= st0.clients_reaped + 1;
		if (!reaped)
			sleep_ms(100);
	}
	printf("victim reaped %llu ms after SIGKILL (clients %u, reaped %llu)\n",
	       (unsigned long long)(mono_ms() - killed_at), st.clients,
	       (unsigned long long)st.clients_reaped);
	TEST_ASSERT_TRUE_MESSAGE(reaped, "the killed client was not reaped");
	mbx_line_status ls;
	TEST_ASSERT_EQUAL_INT(0, cogw_line_status(h, 0, &ls, 0));
	TEST_ASSERT_EQUAL_UINT32(1, ls.clients);
	/* its queues: its process is gone, so the daemon removed them as well */
	int queues = count_client_queues(INSTANCE, v->pid, true);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, queues, "a dead client's queues were left in /dev/mqueue");

	/* the next transfer to the same node gets the channel and all data */
	uint8_t *want = malloc(BIG_SIZE), *back = malloc(DOMAIN_MAX);
	TEST_ASSERT_NOT_NULL(want);
	TEST_ASSERT_NOT_NULL(back);
	fill_pattern(want, BIG_SIZE, KILL_SEED);
	cogw_sdo_opts block = { .mode = 3 };
	size_t len = 0;
	uint32_t abort = 0;
	uint64_t t0 = mono_ms();
	int rc = cogw_sdo_read_ex(h, 0, NODE_PT, DOMAIN_A, 0, &block, back, DOMAIN_MAX, &len,
				  120000, &abort);
	printf("100 KiB block upload after the kill: %s in %llu ms\n", cogw_strerror(rc),
	       (unsigned long long)(mono_ms() - t0));
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
	TEST_ASSERT_EQUAL_size_t(BIG_SIZE, len);
	TEST_ASSERT_EQUAL_MEMORY(want, back, BIG_SIZE);
	free(want);
	free(back);
	close(can);
	cogw_close(h);
	stop_system_and_check();
}

/* ---- 3. a flooding client does not starve the others ----------------------------------- */

static int child_flooder(child_ctx *cx)
{
	cogw *h = NULL;
	int rc = -1;
	uint64_t sent = 0, answered = 0, refused = 0, t0 = mono_us();
	int open_rc_ = open_client(&h, 0);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	mbx_obj_req o = { .index = 0x1017, .sub = 0 }; /* local OD read, line 0 */
	bool said = false;
	while (!child_told(cx, "stop")) {
		for (int i = 0; i < 16; i++) {
			uint64_t corr;
			int s = cogw_send_async(h, 0, MBX_CMD_OD_READ, &o, sizeof o, &corr);
			if (s == 0)
				sent++;
			else
				refused++;
		}
		/* read answers lazily: whatever is there, no waiting */
		cogw_msg m;
		while (cogw_recv(h, &m, 0) == 0) {
			if (m.kind == MBX_KIND_RESPONSE && m.status == 0 && m.len == 2 &&
			    m.data[0] == 0xE8 && m.data[1] == 0x03)
				answered++;
			cogw_msg_release(&m);
		}
		if (!said && sent >= 256) {
			child_say(cx, "flooding");
			said = true;
		}
		CK(mono_us() - t0 < 600000000u, "never told to stop");
	}
	double secs = (double)(mono_us() - t0) / 1e6;
	cogw_stats st;
	cogw_get_stats(h, &st);
	child_say(cx,
		  "flood: %llu commands in %.1f s (%.0f/s), %llu answers read, %llu sends failed, "
		  "%llu async answers dropped by libcogw, %llu overflow flags",
		  (unsigned long long)sent, secs, (double)sent / secs, (unsigned long long)answered,
		  (unsigned long long)refused, (unsigned long long)st.async_dropped,
		  (unsigned long long)st.overflow_flags);
	CK(answered > 0, "no answer at all");
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

#define SERVED_ROUNDS 100

/* A served client: SERVED_ROUNDS x (remote SDO read + local OD read) on
 * its line (line 2 has no device: ping + local read). */
static int child_served(child_ctx *cx)
{
	const unsigned line = (unsigned)(uintptr_t)cx->arg;
	cogw *h = NULL;
	int rc = -1;
	uint64_t lat[2 * SERVED_ROUNDS];
	unsigned n = 0;
	int open_rc_ = open_client(&h, 0);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	CK(cogw_ping(h, line, 0) == 0, "first ping");
	child_say(cx, "ready");
	CK(child_wait(cx, "go", 120000), "no go");
	for (unsigned r = 0; r < SERVED_ROUNDS; r++) {
		uint32_t v = 0, abort = 0;
		uint64_t t = mono_us();
		int s;
		if (line == 0) {
			s = cogw_sdo_read_u32(h, 0, NODE_PT, 0x1018, 1, &v, 10000, &abort);
			CK(s == 0 && v == 0x250, "SDO 1018:01 of node 1: %s %08x value %x",
			   cogw_strerror(s), abort, v);
		} else if (line == 1) {
			s = cogw_sdo_read_u32(h, 1, NODE_IO, 0x1018, 4, &v, 10000, &abort);
			CK(s == 0 && v == 200001, "SDO 1018:04 of node 2: %s %08x value %u",
			   cogw_strerror(s), abort, v);
		} else {
			s = cogw_ping(h, line, 10000);
			CK(s == 0, "ping: %s", cogw_strerror(s));
		}
		lat[n++] = mono_us() - t;
		uint8_t b[4];
		size_t len = 0;
		t = mono_us();
		s = cogw_od_read(h, line, 0x1017, 0, b, sizeof b, &len, 10000, &abort);
		CK(s == 0 && len == 2 && b[0] == 0xE8 && b[1] == 0x03, "local 1017h: %s len %zu",
		   cogw_strerror(s), len);
		lat[n++] = mono_us() - t;
	}
	qsort(lat, n, sizeof lat[0], cmp_u64);
	child_say(cx, "line %u: %u requests, latency p50 %.1f ms, p90 %.1f ms, max %.1f ms", line,
		  n, (double)lat[n / 2] / 1000.0, (double)lat[n * 9 / 10] / 1000.0,
		  (double)lat[n - 1] / 1000.0);
	CK(lat[n - 1] < 2000000u, "a request took %.1f ms (liveness bound 2 s)",
	   (double)lat[n - 1] / 1000.0);
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

static void test_flooding_client_does_not_starve_the_others(void)
{
	start_system();
	child *served[4];
	/* two on line 0 (the flooded one), one on line 1, one on line 2 */
	static const unsigned lines[4] = { 0, 0, 1, 2 };
	for (int i = 0; i < 4; i++) {
		char name[24];
		snprintf(name, sizeof name, "served-%d", i);
		served[i] = child_start(name, child_served, (void *)(uintptr_t)lines[i]);
	}
	for (int i = 0; i < 4; i++)
		TEST_ASSERT_TRUE_MESSAGE(child_expect(served[i], "ready", 60000),
					 "client not ready");
	/* the same requests without the flood, for comparison */
	printf("without flood:\n");
	child *base = child_start("baseline", child_served, (void *)(uintptr_t)0);
	TEST_ASSERT_TRUE(child_expect(base, "ready", 60000));
	child_send(base, "go");
	TEST_ASSERT_TRUE_MESSAGE(child_join(base, 300000), "baseline client failed");

	child *flood = child_start("flooder", child_flooder, NULL);
	TEST_ASSERT_TRUE_MESSAGE(child_expect(flood, "flooding", 60000),
				 "the flooder did not get going");
	mbx_stats_wire st0;
	cogw *h = NULL;
	TEST_ASSERT_EQUAL_INT(0, open_client(&h, 0));
	TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(h, 0, &st0, 0));
	printf("with flood on line 0:\n");
	for (int i = 0; i < 4; i++)
		child_send(served[i], "go");
	bool ok = true;
	for (int i = 0; i < 4; i++)
		ok &= child_join(served[i], 300000);
	mbx_stats_wire st1;
	TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(h, 0, &st1, 0));
	child_send(flood, "stop");
	ok &= child_join(flood, 60000);
	printf("line 0 mailbox while the others ran: %llu commands handled, %llu messages dropped "
	       "(full client queues)\n",
	       (unsigned long long)(st1.commands_ok - st0.commands_ok),
	       (unsigned long long)(st1.dropped - st0.dropped));
	cogw_close(h);
	TEST_ASSERT_TRUE_MESSAGE(ok, "a client failed (see its lines above)");
	stop_system_and_check();
}

/* ---- 4. default configuration, three clients, nothing lost or misrouted ------------------ */

typedef struct tally {
	unsigned sent, received;
} tally;

/* Async requests: n local OD reads of 1017h (1000 ms) on `line`, answers
 * matched by correlation id. */
static int async_batch(cogw *h, unsigned line, unsigned n, tally *t, char *err, size_t cap)
{
	uint64_t corr[8];
	bool got[8] = { false };
	mbx_obj_req o = { .index = 0x1017, .sub = 0 };
	if (n > 8)
		n = 8;
	for (unsigned i = 0; i < n; i++) {
		int s = cogw_send_async(h, line, MBX_CMD_OD_READ, &o, sizeof o, &corr[i]);
		if (s)
			return snprintf(err, cap, "send_async: %s", cogw_strerror(s)), -1;
		t->sent++;
	}
	for (unsigned left = n; left;) {
		cogw_msg m;
		int s = cogw_recv(h, &m, 30000);
		if (s)
			return snprintf(err, cap, "recv: %s (%u answers missing)", cogw_strerror(s),
					left),
			       -1;
		unsigned i = 0;
		while (i < n && (corr[i] != m.corr || got[i]))
			i++;
		bool ok = m.kind == MBX_KIND_RESPONSE && i < n && m.code == MBX_CMD_OD_READ &&
			  m.line == line && m.status == 0 && m.len == 2 && m.data[0] == 0xE8 &&
			  m.data[1] == 0x03;
		if (!ok)
			snprintf(err, cap,
				 "unexpected message kind %u code %04x line %u corr %llu status %d "
				 "len %zu",
				 m.kind, m.code, m.line, (unsigned long long)m.corr, m.status,
				 m.len);
		cogw_msg_release(&m);
		if (!ok)
			return -1;
		got[i] = true;
		left--;
		t->received++;
	}
	return 0;
}

#define COUNT(t, call_ok) ((t).sent++, (call_ok) ? ((t).received++, true) : false)

static int child_default(child_ctx *cx)
{
	const unsigned which = (unsigned)(uintptr_t)cx->arg;
	cogw *h = NULL;
	int rc = -1;
	char err[256], str[64];
	tally t = { 0 };
	int open_rc_ = open_client(&h, 0);
	CK(open_rc_ == 0, "cogw_open: %s (errno %d)", cogw_strerror(open_rc_), errno);
	child_say(cx, "ready");
	CK(child_wait(cx, "go", 60000), "no go");
	for (unsigned r = 0; r < 10; r++) {
		uint32_t v = 0, abort = 0;
		int s;
		if (which == 0) { /* line 0, the transducer */
			s = cogw_sdo_read_u32(h, 0, NODE_PT, 0x1000, 0, &v, 0, &abort);
			CK(COUNT(t, s == 0 && v == 0x00040194), "1000h: %s %08x value %08x",
			   cogw_strerror(s), abort, v);
			s = cogw_sdo_read_string(h, 0, NODE_PT, 0x1008, 0, str, sizeof str, 0,
						 &abort);
			CK(COUNT(t, s == 0 && strcmp(str, "STI-SIM") == 0), "1008h: %s '%s'",
			   cogw_strerror(s), str);
			float f = 0.25f * (float)(r + 1), g = 0;
			s = cogw_sdo_write_float(h, 0, NODE_PT, 0x2000, 1, f, 0, &abort);
			CK(COUNT(t, s == 0), "write 2000:01: %s %08x", cogw_strerror(s), abort);
			s = cogw_sdo_read_float(h, 0, NODE_PT, 0x2000, 1, &g, 0, &abort);
			CK(COUNT(t, s == 0 && g == f), "2000:01 read back %g, wrote %g (%s)",
			   (double)g, (double)f, cogw_strerror(s));
			CK(async_batch(h, 0, 4, &t, err, sizeof err) == 0, "%s", err);
		} else if (which == 1) { /* line 1, the I/O module */
			s = cogw_sdo_read_u32(h, 1, NODE_IO, 0x1018, 4, &v, 0, &abort);
			CK(COUNT(t, s == 0 && v == 200001), "1018:04: %s value %u",
			   cogw_strerror(s), v);
			s = cogw_sdo_read_string(h, 1, NODE_IO, 0x1008, 0, str, sizeof str, 0,
						 &abort);
			CK(COUNT(t, s == 0 && strcmp(str, "IO-SIM") == 0), "1008h: %s '%s'",
			   cogw_strerror(s), str);
			uint8_t out = (uint8_t)(0x11 * r), in = 0;
			s = cogw_sdo_write_u8(h, 1, NODE_IO, 0x6200, 1, out, 0, &abort);
			CK(COUNT(t, s == 0), "write 6200:01: %s %08x", cogw_strerror(s), abort);
			s = cogw_sdo_read_u8(h, 1, NODE_IO, 0x6200, 1, &in, 0, &abort);
			CK(COUNT(t, s == 0 && in == out), "6200:01 read back %u, wrote %u", in,
			   out);
			CK(async_batch(h, 1, 4, &t, err, sizeof err) == 0, "%s", err);
		} else { /* every line */
			s = cogw_ping(h, 2, 0);
			CK(COUNT(t, s == 0), "ping line 2: %s", cogw_strerror(s));
			mbx_line_status ls;
			s = cogw_line_status(h, r % 3, &ls, 0);
			CK(COUNT(t, s == 0 && ls.node_id == 127), "line status %u: %s node %u",
			   r % 3, cogw_strerror(s), ls.node_id);
			mbx_node_entry tab[8];
			s = cogw_node_table(h, 0, tab, 8, 0);
			bool has1 = false;
			for (int i = 0; i < s && i < 8; i++)
				has1 |= tab[i].node == NODE_PT;
			CK(COUNT(t, s >= 1 && has1), "node table of line 0: %d entries, node 1 %s",
			   s, has1 ? "present" : "missing");
			s = cogw_sdo_read_u32(h, 0, NODE_PT, 0x1018, 1, &v, 0, &abort);
			CK(COUNT(t, s == 0 && v == 0x250), "line 0 1018:01: %s value %x",
			   cogw_strerror(s), v);
			s = cogw_sdo_read_u32(h, 1, NODE_IO, 0x1018, 1, &v, 0, &abort);
			CK(COUNT(t, s == 0 && v == 0x1234), "line 1 1018:01: %s value %x",
			   cogw_strerror(s), v);
			size_t len = 0;
			s = cogw_od_read(h, 2, 0x1008, 0, str, sizeof str - 1, &len, 0, &abort);
			str[s == 0 ? len : 0] = '\0';
			CK(COUNT(t, s == 0 && strcmp(str, "cogw gateway") == 0),
			   "line 2 1008h: %s '%s'", cogw_strerror(s), str);
			CK(async_batch(h, r % 3, 4, &t, err, sizeof err) == 0, "%s", err);
		}
	}
	cogw_stats st;
	cogw_get_stats(h, &st);
	child_say(cx, "sent %u, received %u; stray %llu, overflow flags %llu, async dropped %llu",
		  t.sent, t.received, (unsigned long long)st.stray_responses,
		  (unsigned long long)st.overflow_flags, (unsigned long long)st.async_dropped);
	CK(t.sent == t.received, "sent %u != received %u", t.sent, t.received);
	CK(st.stray_responses == 0 && st.overflow_flags == 0 && st.async_dropped == 0,
	   "messages lost or misrouted");
	rc = 0;
out:
	cogw_close(h);
	return rc;
}

static void test_default_config_three_clients_nothing_lost(void)
{
	instance = "main";
	/* no --config: the embedded default (etc/cogw.json at build time) */
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = NULL,
								    .instance = "main",
								    .n_lines = 3,
								    .notify = true,
								    .drop_notify = true }));
	const char *dev0[] = { "etc/devices/sti-pressure.json", NULL };
	const char *dev1[] = { "etc/devices/io-generic.json", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim1, dmn.dir, 1, dev1, NULL));
	child *c[3];
	for (int i = 0; i < 3; i++) {
		char name[24];
		snprintf(name, sizeof name, "default-%d", i);
		c[i] = child_start(name, child_default, (void *)(uintptr_t)i);
	}
	for (int i = 0; i < 3; i++)
		TEST_ASSERT_TRUE_MESSAGE(child_expect(c[i], "ready", 30000), "client not ready");
	for (int i = 0; i < 3; i++)
		child_send(c[i], "go");
	bool ok = true;
	for (int i = 0; i < 3; i++)
		ok &= child_join(c[i], 300000);
	TEST_ASSERT_TRUE_MESSAGE(ok, "a client failed (see its lines above)");
	stop_system_and_check();
}

/* ---- 5. the release daemon under valgrind ------------------------------------------------ */

static void test_release_daemon_under_valgrind_no_leak_no_error(void)
{
	if (access("/usr/bin/valgrind", X_OK) != 0)
		TEST_IGNORE_MESSAGE("valgrind is not installed");
	if (access("build/rel/bin/cogwd", X_OK) != 0)
		TEST_IGNORE_MESSAGE("build/rel/bin/cogwd not built (make)");
	instance = "main";
	static const char *const vg[] = { "/usr/bin/valgrind",
					  "--leak-check=full",
					  "--errors-for-leak-kinds=definite,indirect",
					  "--error-exitcode=99",
					  "--quiet",
					  NULL };
	uint64_t t0 = mono_ms();
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = NULL,
								    .instance = "main",
								    .n_lines = 3,
								    .notify = true,
								    .drop_notify = true,
								    .binary = "build/rel/bin/cogwd",
								    .wrapper = vg,
								    .ready_timeout_ms = 300000 }));
	printf("cogwd under valgrind ready after %.1f s\n", (double)(mono_ms() - t0) / 1000.0);
	const char *dev0[] = { "etc/devices/sti-pressure.json", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, NULL));

	cogw *h = NULL;
	cogw_options o = { .instance = "main", .timeout_ms = 60000 };
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	TEST_ASSERT_EQUAL_INT(0, cogw_ping(h, 0, 0));
	char name[64];
	size_t len = 0;
	uint32_t abort = 0, v = 0;
	TEST_ASSERT_EQUAL_INT(
		0, cogw_od_read(h, 0, 0x1008, 0, name, sizeof name - 1, &len, 0, &abort));
	name[len] = '\0';
	TEST_ASSERT_EQUAL_STRING("cogw gateway", name);
	int rc = cogw_sdo_read_u32(h, 0, NODE_PT, 0x1018, 1, &v, 0, &abort);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
	TEST_ASSERT_EQUAL_HEX32(0x250, v);
	rc = cogw_sdo_read_string(h, 0, NODE_PT, 0x1008, 0, name, sizeof name, 0, &abort);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
	TEST_ASSERT_EQUAL_STRING("STI-SIM", name);
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 0, MBX_EVC_NMT | MBX_EVC_EMCY, NULL, 0, 0));
	cogw_close(h);

	TEST_ASSERT_EQUAL_INT(0, cosim_stop(&sim0, 5000));
	t0 = mono_ms();
	int st = daemon_stop(&dmn, 180000);
	printf("cogwd under valgrind stopped after %.1f s, status 0x%x\n",
	       (double)(mono_ms() - t0) / 1000.0, st);
	if (!(st != -1 && WIFEXITED(st) && WEXITSTATUS(st) == 0))
		proc_dump_log(dmn.log_path, 80);
	TEST_ASSERT_TRUE_MESSAGE(st != -1 && WIFEXITED(st), "cogwd under valgrind did not exit");
	TEST_ASSERT_NOT_EQUAL_MESSAGE(99, WEXITSTATUS(st),
				      "valgrind found errors or leaks (log above)");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, WEXITSTATUS(st), "cogwd exit status");
	TEST_ASSERT_EQUAL_INT(0, daemon_leftovers("main", NULL, 0, NULL, 0));
}

/* ---- main --------------------------------------------------------------------------------- */

/* COGW_TEST_ONLY=substring runs only the tests whose name contains it. */
#define RUN(fn)                                               \
	do {                                                  \
		const char *only_ = getenv("COGW_TEST_ONLY"); \
		if (!only_ || strstr(#fn, only_))             \
			RUN_TEST(fn);                         \
	} while (0)

int main(void)
{
	/* a child's failure must not kill the parent with SIGPIPE */
	signal(SIGPIPE, SIG_IGN);
	UNITY_BEGIN();
	RUN(test_three_clients_transfer_every_size_and_mode_on_two_lines);
	RUN(test_event_classes_reach_exactly_their_subscribers);
	RUN(test_uploads_in_flight_beyond_the_large_buffers);
	RUN(test_killed_client_is_reaped_and_others_are_served);
	RUN(test_flooding_client_does_not_starve_the_others);
	RUN(test_default_config_three_clients_nothing_lost);
	RUN(test_release_daemon_under_valgrind_no_leak_no_error);
	return UNITY_END();
}
