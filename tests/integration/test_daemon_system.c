/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_daemon_system.c - cogwd as a system service
 * against the real daemon on vcan lines:
 *
 *  - sd_notify on a real NOTIFY_SOCKET: READY=1 only once every line is up,
 *    STATUS= one line, WATCHDOG=1 while WATCHDOG_USEC is set, no pings
 *    while a line thread is stalled (debug.stall_signal + SIGUSR2), pings
 *    again afterwards, STOPPING=1 and exit status 0 on SIGTERM;
 *  - 1010h/1011h: "save" through the mailbox and through an SDO download
 *    from a raw CAN socket, confirmed only once the file is written;
 *    values survive a restart, "load" brings the defaults back, corrupted
 *    state files are ignored with a log line;
 *  - invalid configurations refused with "<file>: <json path>: reason";
 *  - SIGHUP: heartbeat period changes on the bus, a bit-rate change is
 *    refused and logged, access rules apply to new and registered clients;
 *  - malformed mailbox messages, one per header and payload field, with
 *    the answer docs/mailbox.md prescribes and the malformed counter moving;
 *  - a mailbox depth above fs.mqueue.msg_max refused with its sysctl name;
 *  - etc/cogwd.service passes systemd-analyze verify.
 *
 * Runs in the vcan VM (tests/vcan/run -n 3): everything it writes lives
 * below /tmp. Timing checks are loose (software-emulated VM, ASan).
 */
#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <linux/can.h>
#include <mqueue.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "core/od_image.h"
#include "core/store_file.h"
#include "mailbox/cogw.h"
#include "mailbox/proto.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define HB_COB_ID 0x77Fu /* 700h + our node id 127 */
#define SDO_RX_COB_ID 0x67Fu
#define SDO_TX_COB_ID 0x5FFu
#define NOBODY_UID 65534u

static daemon_run d;
static daemon_run d2;
static cogw *client;
static int can_fd = -1;
static pid_t child_pid;
static char scratch_dir[64]; /* for tests that spawn cogwd themselves */

static void raw_close(void);
static int mq_recv_ms(mqd_t q, uint8_t *buf, size_t cap, int timeout_ms);

/* ---- configuration text ----------------------------------------------------- */

typedef struct cfg_params {
	const char *instance;
	unsigned n_lines;    /* 1..3 */
	const char *top;     /* extra top-level keys, each ending with ',' */
	const char *mailbox; /* extra mailbox keys, each ending with ',' */
	const char *line0;   /* extra keys of lines[0], each ending with ',' */
	unsigned bitrate0;   /* 0 = 1000000 */
	const char *iface1;  /* lines[1].interface (NULL = vcan1) */
} cfg_params;

static const char *config_text(char *buf, size_t cap, const cfg_params *p)
{
	char more[512] = "";
	if (p->n_lines >= 2)
		snprintf(more, sizeof more,
			 ",\n    {\"name\": \"line1\", \"interface\": \"%s\", \"bitrate\": "
			 "1000000, \"node_id\": 127}%s",
			 p->iface1 ? p->iface1 : "vcan1",
			 p->n_lines >= 3 ? ",\n    {\"name\": \"line2\", \"interface\": \"vcan2\", "
					   "\"bitrate\": 1000000, \"node_id\": 127}"
					 : "");
	snprintf(buf, cap,
		 "{\n  %s\"version\": 1,\n"
		 "  \"mailbox\": {%s\"instance\": \"%s\"},\n"
		 "  \"lines\": [\n"
		 "    {%s\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": %u, "
		 "\"node_id\": 127}%s\n"
		 "  ]\n}\n",
		 p->top ? p->top : "", p->mailbox ? p->mailbox : "", p->instance,
		 p->line0 ? p->line0 : "", p->bitrate0 ? p->bitrate0 : 1000000u, more);
	return buf;
}

/* ---- small helpers ------------------------------------------------------------ */

static void drain_can(int fd)
{
	struct can_frame f;
	while (recv(fd, &f, sizeof f, MSG_DONTWAIT) > 0)
		;
}

/* Mean spacing in ms of `intervals` consecutive frames with this id (the
 * first frame only starts the clock). -1 on a timeout. */
static long mean_frame_spacing_ms(int fd, uint32_t id, int intervals, int timeout_ms)
{
	uint8_t data[8];
	if (can_wait_id(fd, id, data, timeout_ms) < 0)
		return -1;
	uint64_t first = mono_ms();
	for (int i = 0; i < intervals; i++)
		if (can_wait_id(fd, id, data, timeout_ms) < 0)
			return -1;
	return (long)((mono_ms() - first) / (uint64_t)intervals);
}

static int wait_exit(pid_t pid, int timeout_ms, int *status)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	while (mono_ms() < until) {
		if (proc_exited(pid, status))
			return 0;
		sleep_ms(20);
	}
	return -ETIMEDOUT;
}

static uint16_t od_read_u16(cogw *h, uint16_t index)
{
	uint8_t buf[2] = { 0 };
	size_t len = 0;
	uint32_t abort = 0;
	int rc = cogw_od_read(h, 0, index, 0, buf, sizeof buf, &len, 5000, &abort);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
	TEST_ASSERT_EQUAL_size_t(2, len);
	return (uint16_t)(buf[0] | buf[1] << 8);
}

static void od_write_u16(cogw *h, uint16_t index, uint16_t v)
{
	uint8_t buf[2] = { (uint8_t)v, (uint8_t)(v >> 8) };
	uint32_t abort = 0;
	int rc = cogw_od_write(h, 0, index, 0, buf, sizeof buf, 5000, &abort);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
}

/* The value of record index:sub in a line_store parameter file
 * ("COGWOD1\n" + {u16 index, u8 sub, u32 len, data}), or -1. */
static long state_file_value(const char *path, uint16_t index, uint8_t sub)
{
	uint8_t buf[65536];
	FILE *f = fopen(path, "rb");
	if (!f)
		return -1;
	size_t n = fread(buf, 1, sizeof buf, f);
	fclose(f);
	if (n < 8 || memcmp(buf, "COGWOD1\n", 8) != 0)
		return -1;
	for (size_t pos = 8; pos + 7 <= n;) {
		uint16_t idx = (uint16_t)(buf[pos] | buf[pos + 1] << 8);
		uint32_t len = (uint32_t)buf[pos + 3] | (uint32_t)buf[pos + 4] << 8 |
			       (uint32_t)buf[pos + 5] << 16 | (uint32_t)buf[pos + 6] << 24;
		if (len > n - pos - 7)
			return -1;
		if (idx == index && buf[pos + 2] == sub) {
			long v = 0;
			for (uint32_t i = 0; i < len && i < 4; i++)
				v |= (long)buf[pos + 7 + i] << (8 * i);
			return v;
		}
		pos += 7 + len;
	}
	return -1;
}

static void start_daemon(daemon_run *dr, const char *json, const char *instance, unsigned n_lines,
			 uint64_t watchdog_usec, const char *state_dir)
{
	int rc = daemon_start(dr, &(daemon_opts){ .config_json = json,
						  .instance = instance,
						  .n_lines = n_lines,
						  .notify = true,
						  .watchdog_usec = watchdog_usec,
						  .state_dir = state_dir });
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "cogwd did not come up");
}

static void open_client(const char *instance)
{
	int rc = cogw_open(&client, instance);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
}

/* ---- fixtures ------------------------------------------------------------------ */

void setUp(void)
{
	memset(&d, 0, sizeof d);
	memset(&d2, 0, sizeof d2);
	client = NULL;
	can_fd = -1;
	child_pid = 0;
	scratch_dir[0] = '\0';
}

static void remove_tree(const char *dir)
{
	if (strncmp(dir, "/tmp/cogw-sys-", 14) != 0)
		return;
	char cmd[128];
	snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
	int rc = system(cmd);
	(void)rc;
}

void tearDown(void)
{
	if (child_pid > 0) {
		proc_stop(child_pid, SIGKILL, 2000);
		child_pid = 0;
	}
	cogw_close(client);
	client = NULL;
	if (can_fd >= 0)
		close(can_fd);
	can_fd = -1;
	raw_close();
	/* d2 may run on d's state directory: stop it before d's dir goes */
	daemon_cleanup(&d2);
	daemon_cleanup(&d);
	/* after a failure: no queue of ours may outlive the test */
	if (d2.instance[0])
		daemon_unlink_queues(d2.instance);
	if (d.instance[0])
		daemon_unlink_queues(d.instance);
	if (scratch_dir[0])
		remove_tree(scratch_dir);
}

static void make_scratch_dir(void)
{
	snprintf(scratch_dir, sizeof scratch_dir, "/tmp/cogw-sys-XXXXXX");
	TEST_ASSERT_NOT_NULL(mkdtemp(scratch_dir));
}

/* ---- 1. sd_notify: READY, STATUS, WATCHDOG, stall, STOPPING --------------------- */

static void test_notify_ready_status_watchdog_stall_stopping(void)
{
	char json[4096];
	config_text(json, sizeof json,
		    &(cfg_params){
			    .instance = "sys1",
			    .n_lines = 3,
			    .top = "\"debug\": {\"stall_signal\": true, \"stall_ms\": 6000}, " });
	start_daemon(&d, json, "sys1", 3, 2000000, NULL);

	/* READY=1 came together with a one-line STATUS naming every line
	 * as running (not "starting"): the lines were up before READY. */
	const char *status = strstr(d.ready_text, "STATUS=");
	TEST_ASSERT_NOT_NULL_MESSAGE(status, d.ready_text);
	TEST_ASSERT_NULL_MESSAGE(strchr(status, '\n'), "STATUS must be one line");
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(status, "STATUS=3 lines:"), status);
	for (int i = 0; i < 3; i++) {
		char name[32];
		snprintf(name, sizeof name, "line%d ", i);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(status, name), status);
	}
	TEST_ASSERT_NULL_MESSAGE(strstr(status, "starting"), status);
	/* and every line serves its mailbox right away */
	open_client("sys1");
	for (unsigned line = 0; line < 3; line++) {
		mbx_line_status st;
		int rc = cogw_line_status(client, line, &st, 5000);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
		TEST_ASSERT_EQUAL_UINT8(127, st.node_id);
	}

	/* STATUS= keeps being refreshed; WATCHDOG=1 about every
	 * WATCHDOG_USEC/4 = 500 ms: at least 3 in 3 s, loosely */
	char text[1024];
	TEST_ASSERT_EQUAL_INT(0, notify_wait(&d.ns, "STATUS=", 5000, text, sizeof text));
	int pings = notify_count(&d.ns, "WATCHDOG=1", 3000);
	TEST_ASSERT_GREATER_OR_EQUAL_INT(3, pings);

	/* stall line 0 for 6 s: once the main thread notices (line not
	 * looped for > WATCHDOG_USEC/2), no ping may leave */
	TEST_ASSERT_EQUAL_INT(0, kill(d.pid, SIGUSR2));
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path, "line line0: stalling for 6000 ms", 5000));
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(d.log_path, "withholding the watchdog ping", 5000),
		"the stall was not detected");
	notify_drain(&d.ns);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, notify_count(&d.ns, "WATCHDOG=1", 2000),
				      "WATCHDOG=1 sent while line0 was stalled");
	/* after the stall the pings resume by themselves */
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path, "watchdog pings resume", 10000));
	TEST_ASSERT_EQUAL_INT(0, notify_wait(&d.ns, "WATCHDOG=1", 3000, NULL, 0));
	TEST_ASSERT_GREATER_OR_EQUAL_INT(3, notify_count(&d.ns, "WATCHDOG=1", 3000));

	/* SIGTERM: STOPPING=1, then a clean exit */
	cogw_close(client);
	client = NULL;
	TEST_ASSERT_EQUAL_INT(0, kill(d.pid, SIGTERM));
	TEST_ASSERT_EQUAL_INT(0, notify_wait(&d.ns, "STOPPING=1", 10000, NULL, 0));
	int st = daemon_stop(&d, 10000);
	TEST_ASSERT_TRUE(st != -1 && WIFEXITED(st));
	TEST_ASSERT_EQUAL_INT(0, WEXITSTATUS(st));
	char report[256];
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_leftovers("sys1", NULL, 0, report, sizeof report),
				      report);
}

/* A line that cannot come up: no READY=1 at all, a clear log line, exit 1. */
static void test_no_ready_when_a_line_fails(void)
{
	char json[4096];
	config_text(json, sizeof json,
		    &(cfg_params){ .instance = "sys1b", .n_lines = 2, .iface1 = "vcan9" });
	int rc = daemon_start(&d, &(daemon_opts){ .config_json = json,
						  .instance = "sys1b",
						  .n_lines = 2,
						  .notify = true,
						  .ready_timeout_ms = 20000 });
	TEST_ASSERT_EQUAL_INT(-ECHILD, rc); /* exited before any READY=1 */
	TEST_ASSERT_TRUE(WIFEXITED(d.exit_status));
	TEST_ASSERT_NOT_EQUAL(0, WEXITSTATUS(d.exit_status));
	TEST_ASSERT_TRUE(
		file_contains(d.log_path, "line line1 (vcan9): cannot open the CAN interface"));
	char report[256];
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_leftovers("sys1b", NULL, 0, report, sizeof report),
				      report);
}

/* A valid watchdog_check_ms longer than an idle line sleeps used
 * to stop every WATCHDOG=1 (seen with 60000 and idle lines): systemd then
 * kills a healthy daemon. Now a period that cannot fit is refused at start,
 * and one that fits keeps an idle daemon pinging. */
static void test_watchdog_check_period_fits_the_watchdog(void)
{
	char json[4096];
	config_text(json, sizeof json,
		    &(cfg_params){ .instance = "sys1w",
				   .n_lines = 2,
				   .top = "\"watchdog_check_ms\": 60000," });
	int rc = daemon_start(&d, &(daemon_opts){ .config_json = json,
						  .instance = "sys1w",
						  .n_lines = 2,
						  .notify = true,
						  .watchdog_usec = 2000000,
						  .ready_timeout_ms = 20000 });
	TEST_ASSERT_EQUAL_INT_MESSAGE(-ECHILD, rc, "a check period that cannot fit was accepted");
	TEST_ASSERT_TRUE(WIFEXITED(d.exit_status) && WEXITSTATUS(d.exit_status) != 0);
	TEST_ASSERT_TRUE(file_contains(d.log_path,
				       "watchdog_check_ms 60000 does not fit the systemd watchdog "
				       "period of 2000 ms"));
	daemon_cleanup(&d);

	/* the largest that fits: idle lines, pings all the time */
	config_text(json, sizeof json,
		    &(cfg_params){ .instance = "sys1w",
				   .n_lines = 2,
				   .top = "\"watchdog_check_ms\": 1000," });
	start_daemon(&d, json, "sys1w", 2, 2000000, NULL);
	notify_drain(&d.ns);
	TEST_ASSERT_GREATER_OR_EQUAL_INT(6, notify_count(&d.ns, "WATCHDOG=1", 5000));
	TEST_ASSERT_FALSE(file_contains(d.log_path, "withholding the watchdog ping"));
}

static int run_cogwd(const char *config, const char *extra, const char *log, int timeout_ms);

/* A FIFO at the configuration path or at a state-file path
 * blocked start-up, --check and a reload for ever (and with a reload,
 * SIGTERM too). Now: refused as "not a regular file", at once. */
static void test_special_files_do_not_block(void)
{
	char json[4096], fifo[300], log[300], comm[300];
	config_text(json, sizeof json, &(cfg_params){ .instance = "sys1f", .n_lines = 1 });
	start_daemon(&d, json, "sys1f", 1, 0, NULL);

	/* --check on a FIFO: a clear error, no wait */
	snprintf(fifo, sizeof fifo, "%s/fifo.json", d.dir);
	snprintf(log, sizeof log, "%s/check.log", d.dir);
	TEST_ASSERT_EQUAL_INT(0, mkfifo(fifo, 0600));
	TEST_ASSERT_NOT_EQUAL(0, run_cogwd(fifo, "--check", log, 10000));
	TEST_ASSERT_TRUE(file_contains(log, "not a regular file"));

	/* a FIFO at a file the configuration names (a node's DCF, its concise
	 * DCF, its program image): --check refuses at once, with the path */
	char named[300], cfg_path[300], line0[600], json2[4096];
	static const char *const node_keys[] = {
		"\"config\": {\"dcf\": \"%s\"}",
		"\"config\": {\"concise\": \"%s\"}",
		"\"software_id\": 1, \"software_update\": true, \"program\": \"%s\"",
	};
	snprintf(named, sizeof named, "%s/node.fifo", d.dir);
	snprintf(cfg_path, sizeof cfg_path, "%s/named.json", d.dir);
	TEST_ASSERT_EQUAL_INT(0, mkfifo(named, 0600));
	for (size_t i = 0; i < sizeof node_keys / sizeof node_keys[0]; i++) {
		char keys[400];
		snprintf(keys, sizeof keys, node_keys[i], named);
		snprintf(line0, sizeof line0, "\"manager\": {}, \"nodes\": [{\"id\": 2, %s}],",
			 keys);
		config_text(json2, sizeof json2,
			    &(cfg_params){ .instance = "sys1f", .n_lines = 1, .line0 = line0 });
		TEST_ASSERT_EQUAL_INT(0, write_text_file(cfg_path, json2));
		TEST_ASSERT_NOT_EQUAL(0, run_cogwd(cfg_path, "--check", log, 10000));
		TEST_ASSERT_TRUE_MESSAGE(file_contains(log, "node.fifo: not a regular file"), keys);
		TEST_ASSERT_TRUE_MESSAGE(file_contains(log, "lines[0].nodes[0]."), keys);
	}
	/* a reload whose node DCF is a FIFO: refused at once, the daemon
	 * goes on serving */
	snprintf(line0, sizeof line0,
		 "\"manager\": {}, \"nodes\": [{\"id\": 2, \"config\": {\"dcf\": \"%s\"}}],",
		 named);
	config_text(json2, sizeof json2,
		    &(cfg_params){ .instance = "sys1f", .n_lines = 1, .line0 = line0 });
	TEST_ASSERT_EQUAL_INT(0, write_text_file(d.config_path, json2));
	TEST_ASSERT_EQUAL_INT(0, kill(d.pid, SIGHUP));
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path, "node.fifo: not a regular file", 5000));
	open_client("sys1f");
	TEST_ASSERT_EQUAL_INT(0, cogw_ping(client, 0, 5000));
	cogw_close(client);
	client = NULL;

	/* reload with the config path turned into a FIFO: refused, the daemon
	 * goes on and still stops on SIGTERM */
	TEST_ASSERT_EQUAL_INT(0, unlink(d.config_path));
	TEST_ASSERT_EQUAL_INT(0, mkfifo(d.config_path, 0600));
	TEST_ASSERT_EQUAL_INT(0, kill(d.pid, SIGHUP));
	char config_fifo[400];
	snprintf(config_fifo, sizeof config_fifo, "%s: not a regular file", d.config_path);
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path, config_fifo, 5000));
	open_client("sys1f");
	TEST_ASSERT_EQUAL_INT(0, cogw_ping(client, 0, 5000));
	cogw_close(client);
	client = NULL;
	int st = daemon_stop(&d, 10000);
	TEST_ASSERT_TRUE_MESSAGE(st != -1 && WIFEXITED(st), "SIGTERM did not stop the daemon");

	/* a FIFO at the state file path: start-up goes on, configured values */
	snprintf(comm, sizeof comm, "%s/line0.od.comm", d.state_dir);
	mkdir(d.state_dir, 0750);
	unlink(comm);
	TEST_ASSERT_EQUAL_INT(0, mkfifo(comm, 0600));
	daemon_cleanup(&d2);
	start_daemon(&d2, json, "sys1f", 1, 0, d.state_dir);
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "line0.od.comm is not a regular file"));
}

/* With mlockall, max_transfer 64 MiB on 3 lines pinned
 * 1.2 GB (every transfer buffer locked at start-up). Now buffers are
 * locked as they are first used, and start-up reports what is reserved
 * and what is locked. 2 lines x 32 MiB here: 384 MiB of buffers. */
static long daemon_status_kb(pid_t pid, const char *name)
{
	char path[64], text[256];
	long kb = -1;
	size_t n = strlen(name);
	snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
	FILE *f = fopen(path, "r");
	if (!f)
		return -1;
	while (fgets(text, sizeof text, f))
		if (!strncmp(text, name, n) && text[n] == ':' &&
		    sscanf(text + n + 1, "%ld", &kb) == 1)
			break;
	fclose(f);
	return kb;
}

/* ---- a client carries on after the daemon is killed and
 * restarted (the systemd watchdog's restart) ---------------------------------- */

static int in_flight_rc;

/* An SDO upload from node 5, which nobody plays: under way for seconds. */
static void *sdo_in_flight(void *arg)
{
	uint8_t buf[8];
	size_t len = 0;
	uint32_t abort = 0;
	cogw_sdo_opts o = { .sdo_timeout_ms = 8000 };
	(void)arg;
	in_flight_rc = cogw_sdo_read_ex(client, 0, 5, 0x1000, 0, &o, buf, sizeof buf, &len, 30000,
					&abort);
	return NULL;
}

static void test_client_survives_a_daemon_kill_and_restart(void)
{
	char json[4096];
	cfg_params p = { .instance = "sys1r",
			 .n_lines = 1,
			 .line0 = "\"objects\": [{\"index\": \"0x2000\", \"type\": "
				  "\"UNSIGNED16\", \"default\": 7}], " };
	config_text(json, sizeof json, &p);
	start_daemon(&d, json, "sys1r", 1, 0, NULL);
	open_client("sys1r");
	TEST_ASSERT_EQUAL_UINT16(7, od_read_u16(client, 0x2000));
	pthread_t t;
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&t, NULL, sdo_in_flight, NULL));
	struct timespec ts = { 0, 500 * 1000000L };
	nanosleep(&ts, NULL); /* the upload is under way */
	/* killed, as a watchdog restart or a crash ends it: nothing cleaned up */
	kill(d.pid, SIGKILL);
	int st = 0;
	TEST_ASSERT_EQUAL_INT(0, wait_exit(d.pid, 5000, &st));
	d.pid = 0;
	start_daemon(&d2, json, "sys1r", 1, 0, d.state_dir);
	pthread_join(t, NULL);
	/* the request under way: one clear error, long before its timeout */
	TEST_ASSERT_EQUAL_INT_MESSAGE(COGW_E_RESTARTED, in_flight_rc, cogw_strerror(in_flight_rc));
	/* then normal service, on a new registration, as before */
	TEST_ASSERT_EQUAL_UINT16(7, od_read_u16(client, 0x2000));
	od_write_u16(client, 0x2000, 9);
	TEST_ASSERT_EQUAL_UINT16(9, od_read_u16(client, 0x2000));
}

/* ---- transfers that are never acknowledged, the
 * transfer memory budget ------------------------------------------------------ */

#define XFER_OBJ_SIZE (1u << 20) /* 1 MiB DOMAIN 2100h on both lines */
#define XFER_MAX_TRANSFER XFER_OBJ_SIZE
#define XFER_BUDGET (2 * XFER_OBJ_SIZE) /* readers: all but max_transfer of it */

/* A raw mailbox client of the uid that runs it (the misbehaving side runs
 * as 65534 in a forked child, as `setpriv --reuid=65534 --regid=65534
 * --clear-groups` would run it). A response queue of depth 2: the line
 * streams a chunked answer one unacknowledged chunk at a time. */
typedef struct nobody_client {
	mqd_t cmd, resp, evt;
	char rn[64], en[64];
	uint32_t id;
	uint64_t token;
	uint8_t line;
} nobody_client;

static int nobody_send(nobody_client *c, uint16_t code, uint64_t corr, const void *p, size_t len)
{
	mbx_hdr h = { .magic = MBX_MAGIC,
		      .version = MBX_VERSION,
		      .kind = MBX_KIND_COMMAND,
		      .code = code,
		      .line = c->line,
		      .client = c->id,
		      .token = c->token,
		      .corr = corr };
	uint8_t msg[1024];
	int n = mbx_msg_build(msg, sizeof msg, &h, p, len);
	return n > 0 && mq_send(c->cmd, (const char *)msg, (size_t)n, 0) == 0 ? 0 : -1;
}

/* Next response (header only, payload dropped); -1 if none in time. */
static int nobody_recv(nobody_client *c, mbx_hdr *h, int timeout_ms)
{
	uint8_t buf[1024];
	mbx_bad bad;
	int n = mq_recv_ms(c->resp, buf, sizeof buf, timeout_ms);
	return n > 0 && mbx_hdr_decode(buf, (size_t)n, h, &bad) == 0 ? 0 : -1;
}

static int nobody_register(nobody_client *c, const char *instance, unsigned line, const char *tag)
{
	struct mq_attr a = { .mq_maxmsg = 2, .mq_msgsize = 1024 };
	char q[96];
	mbx_register_req r = { .pid = (uint32_t)getpid(), .uid = (uint32_t)getuid() };

	memset(c, 0, sizeof *c);
	snprintf(c->rn, sizeof c->rn, "/cogw.%s.%s%d.resp", instance, tag, (int)getpid());
	snprintf(c->en, sizeof c->en, "/cogw.%s.%s%d.evt", instance, tag, (int)getpid());
	c->resp = mq_open(c->rn, O_RDONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600, &a);
	c->evt = mq_open(c->en, O_RDONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600, &a);
	daemon_cmd_queue(&d, line, q, sizeof q);
	c->line = (uint8_t)line;
	c->cmd = mq_open(q, O_WRONLY | O_CLOEXEC);
	if (c->resp == (mqd_t)-1 || c->evt == (mqd_t)-1 || c->cmd == (mqd_t)-1)
		return -1;
	snprintf(r.resp_queue, sizeof r.resp_queue, "%s", c->rn);
	snprintf(r.event_queue, sizeof r.event_queue, "%s", c->en);
	uint8_t out[1024]; /* mq_receive wants room for the queue's message size */
	if (nobody_send(c, MBX_CMD_REGISTER, 1, &r, sizeof r) < 0 ||
	    mq_recv_ms(c->resp, out, sizeof out, 5000) !=
		    (int)(MBX_HDR_SIZE + sizeof(mbx_register_resp)))
		return -1;
	mbx_register_resp rr;
	memcpy(&rr, out + MBX_HDR_SIZE, sizeof rr);
	c->id = rr.client;
	c->token = rr.token;
	return c->id ? 0 : -1;
}

static void nobody_close(nobody_client *c)
{
	mq_close(c->cmd);
	mq_close(c->resp);
	mq_close(c->evt);
	mq_unlink(c->rn);
	mq_unlink(c->en);
}

/* Child: as uid 65534, start the big read on line 0 and never acknowledge
 * it (mode 'n'), or acknowledge one chunk every 300 ms, well within the
 * stall timeout, for ever (mode 't'): exits 0 when the daemon cut the
 * stream before its end (the slot was taken back), after `go` is closed.
 * Mode 'b': the big read on line 1 must be refused NO_MEMORY. */
static int nobody_reader(const char *instance, char mode, int ready_fd, int go_fd)
{
	nobody_client c;
	mbx_obj_req o = { .index = 0x2100 };
	mbx_hdr h;
	unsigned chunks = 0, last = 0;
	char x = 1;

	if (setgroups(0, NULL) < 0 || setresgid(NOBODY_UID, NOBODY_UID, NOBODY_UID) < 0 ||
	    setresuid(NOBODY_UID, NOBODY_UID, NOBODY_UID) < 0)
		return 10;
	if (nobody_register(&c, instance, mode == 'b' ? 1 : 0, (char[]){ mode, 0 }) < 0)
		return 11;
	if (nobody_send(&c, MBX_CMD_OD_READ, 7, &o, sizeof o) < 0)
		return 12;
	if (nobody_recv(&c, &h, 5000) < 0)
		return 13;
	if (mode == 'b' && h.status != MBX_E_NO_MEMORY)
		return 20 + (h.status < 0 ? -h.status : 0) % 30;
	if (mode != 'b' && !(h.flags & MBX_F_CHUNKED))
		return 13; /* the first chunk: the transfer holds the slot */
	chunks = 1;
	last = h.chunk;
	if (write(ready_fd, &x, 1) != 1)
		return 14;
	if (mode == 't') {
		/* acknowledge every chunk after 300 ms until none comes */
		for (;;) {
			struct timespec ts = { 0, 300 * 1000000L };
			nanosleep(&ts, NULL);
			mbx_xfer_ack a = { .next_chunk = (uint16_t)(last + 1) };
			nobody_send(&c, MBX_CMD_XFER_ACK, 7, &a, sizeof a);
			if (nobody_recv(&c, &h, 2000) < 0)
				break; /* stream cut */
			chunks++;
			last = h.chunk;
			if (!(h.flags & MBX_F_MORE))
				return 15; /* the whole answer came: nothing cut it */
		}
		if (chunks < 4)
			return 16; /* it should have kept the stream going a while */
	}
	if (read(go_fd, &x, 1) < 0)
		return 17;
	nobody_close(&c);
	return 0;
}

static pid_t start_nobody_reader(const char *instance, char mode, int *go_wr)
{
	int ready[2], go[2];
	char x;
	TEST_ASSERT_EQUAL_INT(0, pipe(ready));
	TEST_ASSERT_EQUAL_INT(0, pipe(go));
	pid_t pid = fork();
	TEST_ASSERT_TRUE(pid >= 0);
	if (pid == 0) {
		close(ready[0]);
		close(go[1]);
		_exit(nobody_reader(instance, mode, ready[1], go[0]));
	}
	close(ready[1]);
	close(go[0]);
	if (read(ready[0], &x, 1) != 1) {
		int st = 0;
		waitpid(pid, &st, 0);
		printf("uid 65534 reader: exit %d\n", WIFEXITED(st) ? WEXITSTATUS(st) : -1);
		TEST_FAIL_MESSAGE("the uid 65534 reader did not start its transfer");
	}
	close(ready[0]);
	*go_wr = go[1];
	return pid;
}

static int finish_nobody_reader(pid_t pid, int go_wr)
{
	int st = 0;
	close(go_wr);
	if (wait_exit(pid, 10000, &st) < 0) {
		kill(pid, SIGKILL);
		waitpid(pid, &st, 0);
		return -1;
	}
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Wait until line's MBX_STATS shows at least n expired transfers. */
static mbx_stats_wire wait_expired(unsigned line, uint64_t n)
{
	mbx_stats_wire st;
	for (int i = 0; i < 150; i++) {
		TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(client, line, &st, 5000));
		if (st.xfer_expired >= n)
			return st;
		struct timespec ts = { 0, 200 * 1000000L };
		nanosleep(&ts, NULL);
	}
	TEST_FAIL_MESSAGE("the transfer never lost its slot");
	return st;
}

static int read_big(unsigned line, uint8_t *buf)
{
	size_t len = 0;
	uint32_t abort = 0;
	int rc = cogw_od_read(client, line, 0x2100, 0, buf, XFER_OBJ_SIZE, &len, 20000, &abort);
	if (rc == 0)
		TEST_ASSERT_EQUAL_size_t(XFER_OBJ_SIZE, len);
	return rc;
}

/* Item 5: a client (uid 65534, read-only) that starts a chunked transfer
 * and never acknowledges it, and one that acknowledges a chunk now and
 * then for ever, lose the line's only transfer slot after
 * transfer_stall_ms / transfer_lifetime_ms; each is counted, and another
 * client gets the slot. Item 9: the transfer memory budget is one for all
 * lines - while the stalled 1 MiB answer on line 0 holds its memory,
 * another read-only client's 1 MiB answer on line 1 is refused NO_MEMORY
 * (counted; readers leave max_transfer to writers) and a writer's is
 * served; with mlockall what the daemon pins after the transfers grew by
 * less than the budget (before, every buffer a transfer had touched stayed
 * pinned), and start-up reports the budget. Release build: the
 * sanitizers' shadow memory cannot be locked. */
static void test_transfers_never_acknowledged_and_the_memory_budget(void)
{
	static const char *const inst = "sys1x";
	static char json[4096];
	static uint8_t pattern[XFER_OBJ_SIZE], back[XFER_OBJ_SIZE];
	const char *obj = "\"objects\": [{\"index\": \"0x2100\", \"type\": \"DOMAIN\", "
			  "\"max_size\": 1048576}]";
	snprintf(json, sizeof json,
		 "{\"version\": 1, \"mlockall\": true,\n"
		 " \"mailbox\": {\"instance\": \"%s\", \"queue_mode\": \"0622\",\n"
		 "  \"rules\": [{\"uid\": 65534, \"access\": \"read\"}],\n"
		 "  \"transfer_slots\": 1, \"transfer_stall_ms\": 1000,\n"
		 "  \"transfer_lifetime_ms\": 3000, \"max_transfer\": %u,\n"
		 "  \"transfer_memory\": %u},\n"
		 " \"lines\": [\n"
		 "  {\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": 1000000, "
		 "\"node_id\": 127, %s},\n"
		 "  {\"name\": \"line1\", \"interface\": \"vcan1\", \"bitrate\": 1000000, "
		 "\"node_id\": 127, %s}]}\n",
		 inst, XFER_MAX_TRANSFER, XFER_BUDGET, obj, obj);
	int rc = daemon_start(&d, &(daemon_opts){ .config_json = json,
						  .instance = inst,
						  .n_lines = 2,
						  .notify = true,
						  .binary = "build/rel/bin/cogwd" });
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "cogwd did not come up");
	TEST_ASSERT_TRUE(file_contains(d.log_path, "transfers use at most 2048 KiB at once "
						   "(mailbox.transfer_memory)"));
	TEST_ASSERT_TRUE(file_contains(d.log_path, "pinned in RAM (mlockall)"));
	long rss_start = daemon_status_kb(d.pid, "VmRSS");
	open_client(inst);
	for (size_t i = 0; i < sizeof pattern; i++)
		pattern[i] = (uint8_t)(i * 7 + i / 4096);
	uint32_t abort = 0;
	for (unsigned line = 0; line < 2; line++) {
		rc = cogw_od_write(client, line, 0x2100, 0, pattern, sizeof pattern, 20000, &abort);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
	}

	/* never acknowledged */
	int go;
	pid_t never = start_nobody_reader(inst, 'n', &go);
	TEST_ASSERT_EQUAL_INT_MESSAGE(COGW_E_BUSY, read_big(0, back),
				      "the slot was free while the reader held it");
	/* the budget is one for all lines: another reader's 1 MiB on line 1
	 * does not fit what readers may use (all but max_transfer) */
	int go_b;
	pid_t refused = start_nobody_reader(inst, 'b', &go_b);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, finish_nobody_reader(refused, go_b),
				      "line 1 ignored the memory line 0's transfer holds");
	mbx_stats_wire st1;
	TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(client, 1, &st1, 5000));
	TEST_ASSERT_TRUE(st1.budget_refused >= 1);
	/* a writer still has its max_transfer of the budget */
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, read_big(1, back), "the reader starved a writer");
	mbx_stats_wire st0 = wait_expired(0, 1);
	TEST_ASSERT_TRUE(st0.xfer_failed >= st0.xfer_expired);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, read_big(0, back), "the slot was not given to another");
	TEST_ASSERT_EQUAL_MEMORY(pattern, back, sizeof back);
	TEST_ASSERT_EQUAL_INT(0, finish_nobody_reader(never, go));

	/* acknowledged now and then, for ever: the lifetime ends it */
	pid_t trickle = start_nobody_reader(inst, 't', &go);
	TEST_ASSERT_EQUAL_INT(COGW_E_BUSY, read_big(0, back));
	wait_expired(0, 2);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, read_big(0, back), "the slot was not given to another");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, finish_nobody_reader(trickle, go),
				      "the slowly acknowledged stream was not cut");

	/* every transfer gave its memory back (that its pages go back to the
	 * kernel is test_mbx_budget's; VmRSS here is a figure, not a check:
	 * other allocations of the daemon move it) */
	for (unsigned line = 0; line < 2; line++) {
		mbx_stats_wire st;
		TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(client, line, &st, 5000));
		TEST_ASSERT_EQUAL_UINT64_MESSAGE(0, st.budget_used,
						 "transfer memory not given back");
	}
	long rss_end = daemon_status_kb(d.pid, "VmRSS");
	printf("memory: VmRSS %ld KiB at start, %ld KiB after 2 MiB written to the objects and "
	       "6 transfers of 1 MiB (budget %u KiB)\n",
	       rss_start, rss_end, XFER_BUDGET / 1024);
	cogw_close(client);
	client = NULL;
}

static void test_memory_locked_by_need_and_reported(void)
{
	char json[4096];
	config_text(json, sizeof json,
		    &(cfg_params){ .instance = "sys1m",
				   .n_lines = 2,
				   .top = "\"mlockall\": true,",
				   .mailbox = "\"max_transfer\": 33554432, "
					      "\"transfer_memory\": 33554432, " });
	/* the release build: the sanitizers' shadow memory cannot be locked */
	int rc = daemon_start(&d, &(daemon_opts){ .config_json = json,
						  .instance = "sys1m",
						  .n_lines = 2,
						  .notify = true,
						  .binary = "build/rel/bin/cogwd" });
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "cogwd did not come up");
	TEST_ASSERT_TRUE(file_contains(d.log_path, "KiB of line buffers reserved as address space "
						   "(max_transfer 33554432 bytes)"));
	TEST_ASSERT_TRUE(file_contains(d.log_path, "KiB pinned in RAM"));
	/* VmLck counts every locked mapping in full; what is pinned in RAM
	 * under mlockall is what is resident: VmRSS */
	long locked = daemon_status_kb(d.pid, "VmLck"), pinned = daemon_status_kb(d.pid, "VmRSS");
	printf("memory: VmLck %ld KiB, VmRSS %ld KiB with 2 lines x max_transfer 32 MiB\n", locked,
	       pinned);
	TEST_ASSERT_TRUE_MESSAGE(locked > 0, "nothing locked: mlockall did not run");
	TEST_ASSERT_TRUE_MESSAGE(pinned > 0 && pinned < 64 * 1024,
				 "the transfer buffers were pinned at start-up");
}

/* ---- 2. store / restore across restarts ---------------------------------------------- */

/* Write a parameter file: image, sealed (core/store_file.h) unless gen is
 * 0, with one byte flipped at flip (if >= 0). */
static void write_state_file(const char *path, const uint8_t *image, size_t n, uint32_t gen,
			     uint32_t set, long flip)
{
	uint8_t buf[512];
	long len = (long)n;
	TEST_ASSERT_TRUE(n + CO_STORE_FILE_TRAILER <= sizeof buf);
	memcpy(buf, image, n);
	if (gen)
		len = co_store_file_seal(buf, n, sizeof buf, gen, set);
	TEST_ASSERT_TRUE(len > 0);
	if (flip >= 0)
		buf[flip] ^= 0x10;
	FILE *f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t((size_t)len, fwrite(buf, 1, (size_t)len, f));
	fclose(f);
}

/* 1001h error register of line 0's own node */
static uint8_t error_register(void)
{
	uint8_t v = 0xEE;
	size_t len = 0;
	uint32_t abort = 0;
	int rc = cogw_od_read(client, 0, 0x1001, 0, &v, 1, &len, 5000, &abort);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
	return v;
}

static void restart_on_same_state(const char *json, const char *instance)
{
	cogw_close(client);
	client = NULL;
	int st = daemon_stop(d2.pid > 0 ? &d2 : &d, 10000);
	TEST_ASSERT_TRUE(st != -1 && WIFEXITED(st) && WEXITSTATUS(st) == 0);
	/* d keeps the state directory; every later run uses it through d2 */
	daemon_cleanup(&d2);
	start_daemon(&d2, json, instance, 1, 0, d.state_dir);
	open_client(instance);
}

static void sdo_expedited_download(uint16_t index, uint8_t sub, const uint8_t val[4],
				   uint8_t resp[8])
{
	uint8_t req[8] = { 0x23,   (uint8_t)index, (uint8_t)(index >> 8), sub, val[0], val[1],
			   val[2], val[3] };
	drain_can(can_fd);
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, SDO_RX_COB_ID, req, 8));
	TEST_ASSERT_EQUAL_INT_MESSAGE(8, can_wait_id(can_fd, SDO_TX_COB_ID, resp, 5000),
				      "no SDO answer");
}

static void test_store_restore_survives_restart(void)
{
	char json[4096];
	config_text(json, sizeof json, &(cfg_params){ .instance = "sys2", .n_lines = 1 });
	start_daemon(&d, json, "sys2", 1, 0, NULL);
	open_client("sys2");
	char comm[256], app[256];
	snprintf(comm, sizeof comm, "%s/line0.od.comm", d.state_dir);
	snprintf(app, sizeof app, "%s/line0.od.app", d.state_dir);

	/* mailbox STORE: confirmed only once both parts are on disk */
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));
	od_write_u16(client, 0x1017, 250);
	TEST_ASSERT_EQUAL_INT(0, cogw_store(client, 0, 1, 5000));
	TEST_ASSERT_EQUAL_INT(0, access(comm, F_OK));
	TEST_ASSERT_EQUAL_INT(0, access(app, F_OK));
	TEST_ASSERT_EQUAL_INT32(250, state_file_value(comm, 0x1017, 0));

	/* SDO "save" to 1010h:1 from a raw CAN client: the confirmation
	 * 60 10 10 01 comes only after the new value is in the file */
	od_write_u16(client, 0x1017, 300);
	can_fd = can_open_raw("vcan0");
	TEST_ASSERT_GREATER_OR_EQUAL_INT(0, can_fd);
	uint8_t resp[8];
	static const uint8_t wrong[4] = { 's', 'a', 'v', 'x' };
	sdo_expedited_download(0x1010, 1, wrong, resp);
	static const uint8_t abort_store[8] = { 0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08 };
	TEST_ASSERT_EQUAL_HEX8_ARRAY(abort_store, resp, 8); /* wrong signature: 0800 0020h */
	TEST_ASSERT_EQUAL_INT32(250, state_file_value(comm, 0x1017, 0));
	static const uint8_t save[4] = { 's', 'a', 'v', 'e' }; /* 73 61 76 65 */
	sdo_expedited_download(0x1010, 1, save, resp);
	static const uint8_t confirm[8] = { 0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0 };
	TEST_ASSERT_EQUAL_HEX8_ARRAY(confirm, resp, 8);
	TEST_ASSERT_EQUAL_INT32(300, state_file_value(comm, 0x1017, 0));
	TEST_ASSERT_TRUE(
		file_wait_contains(d.log_path, "line line0: parameters saved (1010h sub 1)", 3000));

	/* restart: the value survived */
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_EQUAL_UINT16(300, od_read_u16(client, 0x1017));
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "line line0: loaded"));

	/* "load" (1011h) through the mailbox removes the files; the running
	 * value stays until the next start, which brings the default back */
	TEST_ASSERT_EQUAL_INT(0, cogw_restore(client, 0, 1, 5000));
	TEST_ASSERT_EQUAL_INT(-1, access(comm, F_OK));
	TEST_ASSERT_EQUAL_INT(ENOENT, errno);
	TEST_ASSERT_EQUAL_INT(-1, access(app, F_OK));
	TEST_ASSERT_EQUAL_UINT16(300, od_read_u16(client, 0x1017));
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));

	/* a corrupted file is ignored with a log line, never a crash */
	TEST_ASSERT_EQUAL_INT(0, write_text_file(comm, "this is not a parameter file\n"));
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "is not a cogw parameter file; ignored"));
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));

	/* a file with one good record (1017h = 400), one for an object that
	 * does not exist and a truncated one: the good one is applied, the
	 * others skipped and said so */
	static const uint8_t mixed[] = {
		'C',  'O',  'G',  'W',  'O',  'D',  '1',  '\n', 0x17,
		0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0x90, 0x01,       /* 1017h:0 = 400 */
		0xFF, 0x5F, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, /* 5FFFh: absent */
		0x05, 0x10, 0x00, 0xFF, 0x00, 0x00, 0x00, 0x01,       /* truncated */
	};
	/* Damaged saved values are never half-applied. Before,
	 * each of these loaded 1017h = 400 (a truncated file with a warning,
	 * a flipped bit silently as another value, a save cut between its two
	 * files half old, half new); now: the configured values, an error
	 * in the log and EMCY 6300h (1001h generic error bit). */
	write_state_file(comm, mixed, sizeof mixed, 0, 0, -1); /* no seal: truncated / foreign */
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "has no checksum"));
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "none of them loaded"));
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));
	TEST_ASSERT_EQUAL_HEX8(0x01, error_register() & 0x01);
	write_state_file(comm, mixed, sizeof mixed, 5, CO_OD_IMAGE_COMM,
			 16); /* 400 -> another value */
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "fails its checksum (damaged)"));
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));
	TEST_ASSERT_EQUAL_HEX8(0x01, error_register() & 0x01);
	static const uint8_t app_image[] = { 'C', 'O', 'G', 'W', 'O', 'D', '1', '\n' };
	write_state_file(comm, mixed, sizeof mixed, 7, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP, -1);
	write_state_file(app, app_image, sizeof app_image, 6, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP,
			 -1);
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_TRUE(file_contains(d2.log_path, "belongs to an interrupted save"));
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));
	TEST_ASSERT_EQUAL_HEX8(0x01, error_register() & 0x01);
	TEST_ASSERT_EQUAL_INT(0, unlink(app));

	/* whole and sealed: applied (the records the dictionary does not
	 * know are skipped: a configuration that changed, not damage) */
	write_state_file(comm, mixed, sizeof mixed, 8, CO_OD_IMAGE_COMM, -1);
	restart_on_same_state(json, "sys2");
	TEST_ASSERT_TRUE(
		file_contains(d2.log_path, "did not match the dictionary and were skipped"));
	TEST_ASSERT_EQUAL_UINT16(400, od_read_u16(client, 0x1017));
}

/* What NMT reset node / reset communication bring
 * back follows 1010h/1011h at run time, not only at the next start. The
 * frames (CiA 301 §7.5.2.13 "save" signature): 67F#2310100173617665 -> 5FF#60..., 000#817F. */
static void nmt_reset_own(uint8_t cs)
{
	uint8_t f[2] = { cs, 0x7F }, boot[8];
	drain_can(can_fd);
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, 0x000, f, 2));
	TEST_ASSERT_EQUAL_INT_MESSAGE(1, can_wait_id(can_fd, HB_COB_ID, boot, 5000), "no boot-up");
	TEST_ASSERT_EQUAL_HEX8(0x00, boot[0]);
}

static void test_store_takes_effect_at_reset(void)
{
	char json[4096];
	config_text(json, sizeof json, &(cfg_params){ .instance = "sys2r", .n_lines = 1 });
	start_daemon(&d, json, "sys2r", 1, 0, NULL);
	open_client("sys2r");
	can_fd = can_open_raw("vcan0");
	TEST_ASSERT_GREATER_OR_EQUAL_INT(0, can_fd);
	uint8_t resp[8];
	static const uint8_t confirm_save[8] = { 0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0 };
	static const uint8_t save[4] = { 's', 'a', 'v', 'e' };

	/* item 2: 1017h = 1234, save, 1017h = 555, reset node -> 1234
	 * (before the fix: 1000, the configured value) */
	od_write_u16(client, 0x1017, 1234);
	sdo_expedited_download(0x1010, 1, save, resp);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(confirm_save, resp, 8);
	od_write_u16(client, 0x1017, 555);
	nmt_reset_own(0x81);
	TEST_ASSERT_EQUAL_UINT16(1234, od_read_u16(client, 0x1017));
	/* reset communication: the same for the communication area */
	od_write_u16(client, 0x1017, 556);
	nmt_reset_own(0x82);
	TEST_ASSERT_EQUAL_UINT16(1234, od_read_u16(client, 0x1017));
}

static void test_restore_takes_effect_at_reset(void)
{
	char json[4096];
	config_text(json, sizeof json, &(cfg_params){ .instance = "sys2l", .n_lines = 1 });
	start_daemon(&d, json, "sys2l", 1, 0, NULL);
	open_client("sys2l");
	uint8_t resp[8];
	static const uint8_t confirm_load[8] = { 0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0 };
	static const uint8_t load[4] = { 'l', 'o', 'a', 'd' };

	/* item 3: after a restart that loaded the saved values, "load" and
	 * then reset node -> the default (before the fix: 1234 stayed) */
	od_write_u16(client, 0x1017, 1234);
	TEST_ASSERT_EQUAL_INT(0, cogw_store(client, 0, 1, 5000));
	restart_on_same_state(json, "sys2l");
	can_fd = can_open_raw("vcan0");
	TEST_ASSERT_GREATER_OR_EQUAL_INT(0, can_fd);
	TEST_ASSERT_EQUAL_UINT16(1234, od_read_u16(client, 0x1017));
	sdo_expedited_download(0x1011, 1, load, resp);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(confirm_load, resp, 8);
	TEST_ASSERT_EQUAL_UINT16(1234, od_read_u16(client, 0x1017)); /* until the reset */
	nmt_reset_own(0x81);
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));

	/* sub 2 + reset communication, through the mailbox this time */
	od_write_u16(client, 0x1017, 777);
	TEST_ASSERT_EQUAL_INT(0, cogw_store(client, 0, 2, 5000));
	od_write_u16(client, 0x1017, 778);
	nmt_reset_own(0x82);
	TEST_ASSERT_EQUAL_UINT16(777, od_read_u16(client, 0x1017));
	TEST_ASSERT_EQUAL_INT(0, cogw_restore(client, 0, 2, 5000));
	nmt_reset_own(0x82);
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));
}

/* ---- 3. invalid configurations ---------------------------------------------------- */

/* Run cogwd on a config file; returns its exit status, output in log. */
static int run_cogwd(const char *config, const char *extra, const char *log, int timeout_ms)
{
	const char *argv[] = { "build/san/bin/cogwd", "--config", config, extra, NULL };
	unlink(log);
	pid_t pid = proc_spawn(argv, log, NULL);
	TEST_ASSERT_GREATER_THAN_INT(0, pid);
	int status = 0;
	if (wait_exit(pid, timeout_ms, &status) != 0) {
		proc_stop(pid, SIGKILL, 2000);
		proc_dump_log(log, 20);
		TEST_FAIL_MESSAGE("cogwd did not exit on its own");
	}
	TEST_ASSERT_TRUE(WIFEXITED(status));
	return WEXITSTATUS(status);
}

static void test_invalid_config_refused_with_path(void)
{
	make_scratch_dir();
	char path[128], log[128], want[512], json[4096];
	snprintf(log, sizeof log, "%s/cogwd.log", scratch_dir);
	static const struct {
		const char *name;
		const char *json;
		const char *reason; /* after "<file>: " */
	} cases[] = {
		{ "node-id.json",
		  "{\"version\": 1, \"mailbox\": {\"instance\": \"sys3\"}, \"lines\": [\n"
		  " {\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127},\n"
		  " {\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 200}]}\n",
		  "lines[1].node_id: 200 is out of range 1..127" },
		{ "unknown-key.json",
		  "{\"version\": 1, \"mailbox\": {\"instance\": \"sys3\"}, \"lines\": [\n"
		  " {\"interface\": \"vcan0\", \"bitrat\": 1000000, \"node_id\": 127}]}\n",
		  "lines[0].bitrat: unknown key (did you mean \"bitrate\"?)" },
		{ "bad-json.json", "{\n  \"version\": 1\n  \"lines\": []\n}\n",
		  "line 3 column 3: invalid JSON" },
		{ "missing-bitrate.json",
		  "{\"version\": 1, \"mailbox\": {\"instance\": \"sys3\"}, \"lines\": [\n"
		  " {\"interface\": \"vcan0\", \"node_id\": 127}]}\n",
		  "lines[0].bitrate: " },
	};
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		snprintf(path, sizeof path, "%s/%s", scratch_dir, cases[i].name);
		TEST_ASSERT_EQUAL_INT(0, write_text_file(path, cases[i].json));
		snprintf(want, sizeof want, "%s: %s", path, cases[i].reason);
		uint64_t t0 = mono_ms();
		int rc = run_cogwd(path, NULL, log, 10000);
		if (rc == 0 || !file_contains(log, want)) {
			proc_dump_log(log, 10);
			printf("expected: %s\n", want);
		}
		TEST_ASSERT_NOT_EQUAL_MESSAGE(0, rc, cases[i].name);
		TEST_ASSERT_TRUE_MESSAGE(file_contains(log, want), cases[i].name);
		TEST_ASSERT_LESS_THAN_UINT64_MESSAGE(8000, mono_ms() - t0, "refusal took too long");
		/* --check gives the same verdict without starting anything */
		rc = run_cogwd(path, "--check", log, 10000);
		TEST_ASSERT_NOT_EQUAL(0, rc);
		TEST_ASSERT_TRUE_MESSAGE(file_contains(log, want), cases[i].name);
	}
	char report[256];
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_leftovers("sys3", NULL, 0, report, sizeof report),
				      report);

	/* a file that does not exist */
	snprintf(path, sizeof path, "%s/absent.json", scratch_dir);
	TEST_ASSERT_NOT_EQUAL(0, run_cogwd(path, NULL, log, 10000));
	snprintf(want, sizeof want, "%s: cannot open: No such file or directory", path);
	TEST_ASSERT_TRUE(file_contains(log, want));

	/* the good one passes --check */
	snprintf(path, sizeof path, "%s/good.json", scratch_dir);
	config_text(json, sizeof json, &(cfg_params){ .instance = "sys3", .n_lines = 3 });
	TEST_ASSERT_EQUAL_INT(0, write_text_file(path, json));
	TEST_ASSERT_EQUAL_INT(0, run_cogwd(path, "--check", log, 10000));
	snprintf(want, sizeof want, "%s: configuration is valid (3 lines)", path);
	TEST_ASSERT_TRUE(file_contains(log, want));
}

/* ---- 6. mqueue system limits ---------------------------------------------------------- */

static void test_depth_above_msg_max_refused(void)
{
	unsigned long msg_max = 0;
	FILE *f = fopen("/proc/sys/fs/mqueue/msg_max", "r");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_INT(1, fscanf(f, "%lu", &msg_max));
	fclose(f);
	TEST_ASSERT_LESS_THAN_UINT64(1000, msg_max); /* 256 in the VM */

	make_scratch_dir();
	char path[128], log[128], want[256], json[4096];
	snprintf(path, sizeof path, "%s/deep.json", scratch_dir);
	snprintf(log, sizeof log, "%s/cogwd.log", scratch_dir);
	config_text(
		json, sizeof json,
		&(cfg_params){ .instance = "sys6", .n_lines = 1, .mailbox = "\"depth\": 1000, " });
	TEST_ASSERT_EQUAL_INT(0, write_text_file(path, json));
	TEST_ASSERT_NOT_EQUAL(0, run_cogwd(path, NULL, log, 10000));
	snprintf(want, sizeof want,
		 "mailbox: fs.mqueue.msg_max is %lu but the mailbox queue depth is 1000: run "
		 "'sysctl -w fs.mqueue.msg_max=1000'",
		 msg_max);
	if (!file_contains(log, want))
		proc_dump_log(log, 10);
	TEST_ASSERT_TRUE(file_contains(log, want));
	char report[256];
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_leftovers("sys6", NULL, 0, report, sizeof report),
				      report);
}

/* ---- 4. SIGHUP reload ----------------------------------------------------------------- */

/* A client process running as another user (uid 65534), driven through
 * pipes: 'r' reads 2000h, 'w' writes it, 'n' reopens the handle; the
 * answer is the libcogw result as an int. */
static int child_cmd_fd = -1, child_res_fd = -1;

static void child_main(int cmd_fd, int res_fd, const char *instance)
{
	if (setgroups(0, NULL) != 0 || setgid(NOBODY_UID) != 0 || setuid(NOBODY_UID) != 0)
		_exit(90);
	cogw *h = NULL;
	int rc = cogw_open(&h, instance);
	char c;
	while (read(cmd_fd, &c, 1) == 1) {
		uint8_t buf[2] = { 0x34, 0x12 };
		size_t len = 0;
		uint32_t abort = 0;
		if (c == 'n') {
			cogw_close(h);
			h = NULL;
			rc = cogw_open(&h, instance);
		} else if (!h) {
			/* rc from the failed open */
		} else if (c == 'r') {
			rc = cogw_od_read(h, 0, 0x2000, 0, buf, sizeof buf, &len, 3000, &abort);
		} else if (c == 'w') {
			rc = cogw_od_write(h, 0, 0x2000, 0, buf, sizeof buf, 3000, &abort);
		} else {
			break;
		}
		if (write(res_fd, &rc, sizeof rc) != (ssize_t)sizeof rc)
			break;
	}
	cogw_close(h);
	_exit(0);
}

static void start_child(const char *instance)
{
	int cmd[2], res[2];
	TEST_ASSERT_EQUAL_INT(0, pipe(cmd));
	TEST_ASSERT_EQUAL_INT(0, pipe(res));
	fflush(stdout);
	child_pid = fork();
	TEST_ASSERT_GREATER_OR_EQUAL_INT(0, child_pid);
	if (child_pid == 0) {
		close(cmd[1]);
		close(res[0]);
		child_main(cmd[0], res[1], instance);
	}
	close(cmd[0]);
	close(res[1]);
	child_cmd_fd = cmd[1];
	child_res_fd = res[0];
}

static int child_do(char c)
{
	int rc = 12345;
	TEST_ASSERT_EQUAL_INT(1, write(child_cmd_fd, &c, 1));
	TEST_ASSERT_EQUAL_INT((int)sizeof rc, read(child_res_fd, &rc, sizeof rc));
	return rc;
}

static void stop_child(void)
{
	/* EOF on its command pipe: the child closes its handle and exits */
	close(child_cmd_fd);
	close(child_res_fd);
	child_cmd_fd = child_res_fd = -1;
	int st = 0;
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, wait_exit(child_pid, 10000, &st),
				      "client child did not exit");
	child_pid = 0;
	TEST_ASSERT_TRUE(WIFEXITED(st));
	TEST_ASSERT_EQUAL_INT(0, WEXITSTATUS(st));
}

static void reload_with(const char *json)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_reload(&d, json, 5000),
				      "no RELOADING=1 and READY=1 after SIGHUP");
}

#define RELOAD_OBJ \
	"\"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED16\", \"default\": 7}], "

static void test_sighup_reload(void)
{
	char json[4096];
	cfg_params p = { .instance = "sys4",
			 .n_lines = 1,
			 .mailbox = "\"queue_mode\": \"0622\", \"default_access\": \"read\", ",
			 .line0 = "\"heartbeat_ms\": 1000, " RELOAD_OBJ };
	can_fd = can_open_raw("vcan0");
	TEST_ASSERT_GREATER_OR_EQUAL_INT(0, can_fd);
	start_daemon(&d, config_text(json, sizeof json, &p), "sys4", 1, 0, NULL);

	long ms = mean_frame_spacing_ms(can_fd, HB_COB_ID, 3, 5000);
	printf("heartbeat spacing before reload: %ld ms\n", ms);
	TEST_ASSERT_INT_WITHIN(300, 1000, ms);

	/* heartbeat_ms 1000 -> 200: applied at run time */
	p.line0 = "\"heartbeat_ms\": 200, " RELOAD_OBJ;
	reload_with(config_text(json, sizeof json, &p));
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path,
					    "reload: line line0 heartbeat 1000 -> 200 ms", 3000));
	drain_can(can_fd);
	ms = mean_frame_spacing_ms(can_fd, HB_COB_ID, 5, 5000);
	printf("heartbeat spacing after reload: %ld ms\n", ms);
	TEST_ASSERT_INT_WITHIN(150, 250, ms); /* 200 ms, loosely (VM jitter) */

	/* a bit-rate change cannot be applied: refused, logged, nothing
	 * changes (the heartbeat change in the same file is not applied) */
	p.bitrate0 = 500000;
	p.line0 = "\"heartbeat_ms\": 500, " RELOAD_OBJ;
	reload_with(config_text(json, sizeof json, &p));
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path, "reload refused: lines[0].bitrate", 3000));
	drain_can(can_fd);
	ms = mean_frame_spacing_ms(can_fd, HB_COB_ID, 5, 5000);
	TEST_ASSERT_INT_WITHIN(150, 250, ms); /* still 200 ms, not 500 */

	/* access rules: a client of user 65534 is read-only by default */
	p.bitrate0 = 0;
	p.line0 = "\"heartbeat_ms\": 200, " RELOAD_OBJ;
	start_child("sys4");
	TEST_ASSERT_EQUAL_INT(0, child_do('r'));
	TEST_ASSERT_EQUAL_INT(COGW_E_ACCESS, child_do('w'));
	/* a rule granting write applies to that registered client at once */
	p.mailbox = "\"queue_mode\": \"0622\", \"default_access\": \"read\", "
		    "\"rules\": [{\"uid\": 65534, \"access\": \"write\"}], ";
	reload_with(config_text(json, sizeof json, &p));
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path,
					    "reload: mailbox access: 1 rule, default read", 3000));
	TEST_ASSERT_EQUAL_INT(0, child_do('w'));
	TEST_ASSERT_EQUAL_INT(0, child_do('r'));
	/* "none": the registered client is dropped, a new registration of
	 * that user is refused */
	p.mailbox = "\"queue_mode\": \"0622\", \"default_access\": \"read\", "
		    "\"rules\": [{\"uid\": 65534, \"access\": \"none\"}], ";
	reload_with(config_text(json, sizeof json, &p));
	TEST_ASSERT_TRUE(file_wait_contains(d.log_path,
					    "reload: mailbox access: 1 rule, default read", 3000));
	/* the dropped client's command is not answered (its token is void) */
	TEST_ASSERT_EQUAL_INT(COGW_E_TIMEOUT, child_do('r'));
	TEST_ASSERT_EQUAL_INT(0, child_do('n')); /* queues only */
	TEST_ASSERT_EQUAL_INT(COGW_E_ACCESS, child_do('r'));
	stop_child();

	/* the daemon is still fine and exits cleanly */
	open_client("sys4");
	TEST_ASSERT_EQUAL_UINT16(200, od_read_u16(client, 0x1017));
	cogw_close(client);
	client = NULL;
	int st = daemon_stop(&d, 10000);
	TEST_ASSERT_TRUE(st != -1 && WIFEXITED(st));
	TEST_ASSERT_EQUAL_INT(0, WEXITSTATUS(st));
}

/* ---- 5. malformed mailbox messages --------------------------------------------------- */

/* A hand-made client: registers itself, then sends exact bytes. */
typedef struct raw_client {
	mqd_t cmd, resp, evt;
	char resp_name[64], evt_name[64];
	uint32_t id;
	uint64_t token;
	uint64_t corr;
} raw_client;

static raw_client rc_ = { .cmd = (mqd_t)-1, .resp = (mqd_t)-1, .evt = (mqd_t)-1 };

static int mq_recv_ms(mqd_t q, uint8_t *buf, size_t cap, int timeout_ms)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	ts.tv_sec += timeout_ms / 1000;
	ts.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
	if (ts.tv_nsec >= 1000000000L) {
		ts.tv_sec++;
		ts.tv_nsec -= 1000000000L;
	}
	ssize_t n = mq_timedreceive(q, (char *)buf, cap, NULL, &ts);
	return n < 0 ? -errno : (int)n;
}

static mbx_hdr cmd_hdr(uint16_t code)
{
	mbx_hdr h = { .magic = MBX_MAGIC,
		      .version = MBX_VERSION,
		      .kind = MBX_KIND_COMMAND,
		      .code = code,
		      .line = 0,
		      .client = rc_.id,
		      .token = rc_.token,
		      .corr = ++rc_.corr };
	return h;
}

static void raw_send_bytes(const uint8_t *msg, size_t n)
{
	TEST_ASSERT_EQUAL_INT(0, mq_send(rc_.cmd, (const char *)msg, n, 0));
}

/* Next response: its header and payload. -ETIMEDOUT if none. */
static int raw_recv(mbx_hdr *h, uint8_t *payload, size_t cap, int timeout_ms)
{
	uint8_t buf[1024];
	int n = mq_recv_ms(rc_.resp, buf, sizeof buf, timeout_ms);
	if (n < 0)
		return n;
	mbx_bad bad;
	TEST_ASSERT_EQUAL_INT(0, mbx_hdr_decode(buf, (size_t)n, h, &bad));
	TEST_ASSERT_EQUAL_UINT8(MBX_KIND_RESPONSE, h->kind);
	if (payload)
		memcpy(payload, buf + MBX_HDR_SIZE, h->len < cap ? h->len : cap);
	return 0;
}

static void raw_open(const char *instance)
{
	memset(&rc_, 0, sizeof rc_);
	rc_.resp = rc_.evt = rc_.cmd = (mqd_t)-1;
	snprintf(rc_.resp_name, sizeof rc_.resp_name, "/cogw.%s.raw%d.resp", instance,
		 (int)getpid());
	snprintf(rc_.evt_name, sizeof rc_.evt_name, "/cogw.%s.raw%d.evt", instance, (int)getpid());
	struct mq_attr a = { .mq_maxmsg = 8, .mq_msgsize = 1024 };
	mq_unlink(rc_.resp_name);
	mq_unlink(rc_.evt_name);
	rc_.resp = mq_open(rc_.resp_name, O_RDONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600, &a);
	rc_.evt = mq_open(rc_.evt_name, O_RDONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600, &a);
	char q[96];
	daemon_cmd_queue(&d, 0, q, sizeof q);
	rc_.cmd = mq_open(q, O_WRONLY | O_CLOEXEC);
	TEST_ASSERT_TRUE(rc_.resp != (mqd_t)-1 && rc_.evt != (mqd_t)-1 && rc_.cmd != (mqd_t)-1);

	mbx_register_req r = { .pid = (uint32_t)getpid(), .uid = (uint32_t)getuid() };
	snprintf(r.resp_queue, sizeof r.resp_queue, "%s", rc_.resp_name);
	snprintf(r.event_queue, sizeof r.event_queue, "%s", rc_.evt_name);
	mbx_hdr h = cmd_hdr(MBX_CMD_REGISTER);
	h.client = 0;
	h.token = 0;
	uint8_t msg[1024];
	int n = mbx_msg_build(msg, sizeof msg, &h, &r, sizeof r);
	TEST_ASSERT_GREATER_THAN_INT(0, n);
	raw_send_bytes(msg, (size_t)n);
	mbx_hdr rh;
	mbx_register_resp out;
	TEST_ASSERT_EQUAL_INT(0, raw_recv(&rh, (uint8_t *)&out, sizeof out, 5000));
	TEST_ASSERT_EQUAL_INT(0, rh.status);
	TEST_ASSERT_EQUAL_UINT16(sizeof out, rh.len);
	rc_.id = out.client;
	rc_.token = out.token;
	TEST_ASSERT_NOT_EQUAL(0, rc_.id);
}

static void raw_close(void)
{
	if (rc_.cmd != (mqd_t)-1)
		mq_close(rc_.cmd);
	if (rc_.resp != (mqd_t)-1)
		mq_close(rc_.resp);
	if (rc_.evt != (mqd_t)-1)
		mq_close(rc_.evt);
	if (rc_.resp_name[0])
		mq_unlink(rc_.resp_name);
	if (rc_.evt_name[0])
		mq_unlink(rc_.evt_name);
	memset(&rc_, 0, sizeof rc_);
	rc_.cmd = rc_.resp = rc_.evt = (mqd_t)-1;
}

static mbx_stats_wire raw_stats(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_MBX_STATS), rh;
	uint8_t msg[MBX_HDR_SIZE];
	mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	raw_send_bytes(msg, sizeof msg);
	mbx_stats_wire st;
	memset(&st, 0, sizeof st);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, raw_recv(&rh, (uint8_t *)&st, sizeof st, 5000),
				      "no MBX_STATS answer");
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(h.corr, rh.corr,
					 "an unexpected answer came before MBX_STATS");
	TEST_ASSERT_EQUAL_INT(0, rh.status);
	return st;
}

#define NO_ANSWER 1 /* expect_status value: the daemon must stay silent */

typedef struct bad_case {
	const char *what;
	uint16_t code;
	uint8_t payload[600];
	size_t plen;
	int patch_off;  /* header byte to patch, -1 = none */
	int patch_size; /* 1, 2, 4 or 8 bytes, little-endian */
	uint64_t patch_val;
	size_t truncate_to; /* send only this many bytes (0 = all) */
	int expect_status;  /* MBX_E_* answered, or NO_ANSWER */
	uint32_t expect_abort;
	int malformed_delta; /* how much the malformed counter moves */
} bad_case;

static void put_le(uint8_t *p, int size, uint64_t v)
{
	for (int i = 0; i < size; i++)
		p[i] = (uint8_t)(v >> (8 * i));
}

static void run_bad_case(const bad_case *c)
{
	mbx_stats_wire before = raw_stats();
	mbx_hdr h = cmd_hdr(c->code);
	uint8_t msg[1024];
	int n = mbx_msg_build(msg, sizeof msg, &h, c->payload, c->plen);
	TEST_ASSERT_GREATER_THAN_INT_MESSAGE(0, n, c->what);
	if (c->patch_off >= 0)
		put_le(msg + c->patch_off, c->patch_size, c->patch_val);
	raw_send_bytes(msg, c->truncate_to ? c->truncate_to : (size_t)n);
	uint16_t sent_code = (uint16_t)(msg[4] | msg[5] << 8); /* echoed as sent */

	if (c->expect_status != NO_ANSWER) {
		mbx_hdr rh;
		int rc = raw_recv(&rh, NULL, 0, 5000);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, c->what);
		TEST_ASSERT_EQUAL_UINT64_MESSAGE(h.corr, rh.corr, c->what);
		TEST_ASSERT_EQUAL_UINT16_MESSAGE(sent_code, rh.code, c->what);
		TEST_ASSERT_EQUAL_INT_MESSAGE(c->expect_status, rh.status, c->what);
		TEST_ASSERT_EQUAL_HEX32_MESSAGE(c->expect_abort, rh.abort, c->what);
	}
	/* raw_stats() checks that the very next answer is its own, so a
	 * NO_ANSWER case that was answered fails here */
	mbx_stats_wire after = raw_stats();
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(before.malformed + (uint64_t)c->malformed_delta,
					 after.malformed, c->what);
}

/* header field offsets: docs/mailbox.md */
enum {
	OFF_MAGIC = 0,
	OFF_VERSION = 2,
	OFF_KIND = 3,
	OFF_CODE = 4,
	OFF_LINE = 6,
	OFF_FLAGS = 7,
	OFF_CLIENT = 8,
	OFF_STATUS = 12,
	OFF_TOKEN = 24,
	OFF_ABORT = 32,
	OFF_DROPPED = 36,
	OFF_CHUNK = 40,
	OFF_LEN = 42,
	OFF_TOTAL = 44
};

/* A PING with one header field patched; counted malformed once. */
#define HEADER_CASE(what, off, size, val, status)                             \
	{                                                                     \
		what, MBX_CMD_PING, { 0 }, 0, off, size, val, 0, status, 0, 1 \
	}
/* A command with a payload of plen bytes (filled in by the step). */
#define PAYLOAD_CASE(what, code, plen, status, abort, malformed)               \
	{                                                                      \
		what, code, { 0 }, plen, -1, 0, 0, 0, status, abort, malformed \
	}

static void malformed_header_fields(void)
{
	static const bad_case header_cases[] = {
		{ "short message", MBX_CMD_PING, { 0 }, 0, -1, 0, 0, 20, NO_ANSWER, 0, 1 },
		HEADER_CASE("magic", OFF_MAGIC, 2, 0x1234, NO_ANSWER),
		HEADER_CASE("version 2", OFF_VERSION, 1, 2, MBX_E_VERSION),
		HEADER_CASE("kind response", OFF_KIND, 1, MBX_KIND_RESPONSE, MBX_E_MALFORMED),
		HEADER_CASE("kind 9", OFF_KIND, 1, 9, MBX_E_MALFORMED),
		HEADER_CASE("code unknown", OFF_CODE, 2, 0x0999, MBX_E_UNKNOWN_CMD),
		HEADER_CASE("line of another queue", OFF_LINE, 1, 1, MBX_E_BAD_LINE),
		HEADER_CASE("flags unknown bit", OFF_FLAGS, 1, 0x10, MBX_E_MALFORMED),
		HEADER_CASE("flags OVERFLOW from a client", OFF_FLAGS, 1, MBX_F_OVERFLOW,
			    MBX_E_MALFORMED),
		HEADER_CASE("flags MORE without CHUNKED", OFF_FLAGS, 1, MBX_F_MORE,
			    MBX_E_MALFORMED),
		HEADER_CASE("client id unknown", OFF_CLIENT, 4, 0x7FFF0003, NO_ANSWER),
		HEADER_CASE("token wrong", OFF_TOKEN, 8, 0x0123456789ABCDEFull, NO_ANSWER),
		HEADER_CASE("status set by a client", OFF_STATUS, 4, 0xFFFFFFFF, MBX_E_MALFORMED),
		HEADER_CASE("abort set by a client", OFF_ABORT, 4, 0x06020000, MBX_E_MALFORMED),
		HEADER_CASE("dropped set by a client", OFF_DROPPED, 4, 5, MBX_E_MALFORMED),
		HEADER_CASE("len larger than sent", OFF_LEN, 2, 12, MBX_E_MALFORMED),
		HEADER_CASE("chunk without CHUNKED", OFF_CHUNK, 2, 3, MBX_E_MALFORMED),
		HEADER_CASE("total without CHUNKED", OFF_TOTAL, 4, 100, MBX_E_MALFORMED),
		HEADER_CASE("CHUNKED with total 0", OFF_FLAGS, 1, MBX_F_CHUNKED, MBX_E_MALFORMED),
	};
	for (size_t i = 0; i < sizeof header_cases / sizeof header_cases[0]; i++)
		run_bad_case(&header_cases[i]);
}

/* Chunk fields of a data command. */
static void malformed_chunk_fields(void)
{
	/* CHUNKED on a command that never is (PING): flags + total */
	uint8_t msg[MBX_HDR_SIZE];
	mbx_stats_wire before = raw_stats();
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);
	h.flags = MBX_F_CHUNKED;
	h.total = 4;
	mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	raw_send_bytes(msg, sizeof msg);
	mbx_hdr rh;
	TEST_ASSERT_EQUAL_INT(0, raw_recv(&rh, NULL, 0, 5000));
	TEST_ASSERT_EQUAL_UINT64(h.corr, rh.corr);
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, rh.status);
	TEST_ASSERT_EQUAL_UINT64(before.malformed + 1, raw_stats().malformed);

	/* chunk 5 of an OD_WRITE transfer that was never opened */
	uint8_t data[16] = { 1, 2, 3, 4 };
	before = raw_stats();
	h = cmd_hdr(MBX_CMD_OD_WRITE);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE;
	h.chunk = 5;
	h.total = 4096;
	uint8_t big[MBX_HDR_SIZE + 16];
	mbx_msg_build(big, sizeof big, &h, data, sizeof data);
	raw_send_bytes(big, sizeof big);
	TEST_ASSERT_EQUAL_INT(0, raw_recv(&rh, NULL, 0, 5000));
	TEST_ASSERT_EQUAL_UINT64(h.corr, rh.corr);
	TEST_ASSERT_EQUAL_INT(MBX_E_SEQUENCE, rh.status);
	TEST_ASSERT_EQUAL_UINT64(before.malformed + 1, raw_stats().malformed);

	/* chunk 0 that says everything fits (no MORE): not a transfer */
	before = raw_stats();
	mbx_obj_req o = { .index = 0x1017 };
	uint8_t first[4 + 8];
	memcpy(first, &o, sizeof o);
	h = cmd_hdr(MBX_CMD_OD_WRITE);
	h.flags = MBX_F_CHUNKED;
	h.total = 8;
	uint8_t m0[MBX_HDR_SIZE + sizeof first];
	mbx_msg_build(m0, sizeof m0, &h, first, sizeof first);
	raw_send_bytes(m0, sizeof m0);
	TEST_ASSERT_EQUAL_INT(0, raw_recv(&rh, NULL, 0, 5000));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, rh.status);
	TEST_ASSERT_EQUAL_UINT64(before.malformed + 1, raw_stats().malformed);
}

static void malformed_payload_fields(void)
{
	mbx_nmt_req nmt_node = { .cs = 0x01, .node = 128 };
	mbx_nmt_req nmt_cs = { .cs = 0x03, .node = 1 };
	mbx_nmt_req nmt_pad = { .cs = 0x01, .node = 1, .pad = 1 };
	mbx_sdo_req sdo_node0 = { .node = 0, .index = 0x1000 };
	mbx_sdo_req sdo_node128 = { .node = 128, .index = 0x1000 };
	mbx_sdo_req sdo_mode9 = { .node = 1, .mode = 9, .index = 0x1000 };
	mbx_obj_req obj_missing = { .index = 0x5FFF, .sub = 0 };
	mbx_obj_req obj_bad_sub = { .index = 0x1017, .sub = 5 };
	mbx_obj_req obj_flags = { .index = 0x1017, .flags = 1 };
	mbx_raw_frame raw_len9 = { .id = 0x123, .len = 9 };
	mbx_raw_frame raw_id = { .id = 0x800, .len = 0 }; /* 12 bits without EXT */
	mbx_raw_frame raw_dirty = { .id = 0x123, .len = 1, .data = { 1, 2 } };
	mbx_store_req store0 = { .sub = 0 };
	mbx_pdo_num_req pdo0 = { .pdo = 0 };
	bad_case payload_cases[] = {
		PAYLOAD_CASE("NMT node 128", MBX_CMD_NMT, sizeof nmt_node, MBX_E_PARAM, 0, 1),
		PAYLOAD_CASE("NMT cs 0x03", MBX_CMD_NMT, sizeof nmt_cs, MBX_E_PARAM, 0, 1),
		PAYLOAD_CASE("NMT pad", MBX_CMD_NMT, sizeof nmt_pad, MBX_E_MALFORMED, 0, 1),
		PAYLOAD_CASE("NMT short payload", MBX_CMD_NMT, 3, MBX_E_MALFORMED, 0, 1),
		PAYLOAD_CASE("SDO node 0", MBX_CMD_SDO_UPLOAD, sizeof sdo_node0, MBX_E_PARAM, 0, 1),
		PAYLOAD_CASE("SDO node 128", MBX_CMD_SDO_UPLOAD, sizeof sdo_node128, MBX_E_PARAM, 0,
			     1),
		PAYLOAD_CASE("SDO mode 9", MBX_CMD_SDO_UPLOAD, sizeof sdo_mode9, MBX_E_PARAM, 0, 1),
		PAYLOAD_CASE("OD read of a missing object", MBX_CMD_OD_READ, sizeof obj_missing,
			     MBX_E_ABORT, 0x06020000u, 0),
		PAYLOAD_CASE("OD read of a missing sub-index", MBX_CMD_OD_READ, sizeof obj_bad_sub,
			     MBX_E_ABORT, 0x06090011u, 0),
		PAYLOAD_CASE("OD read with flags", MBX_CMD_OD_READ, sizeof obj_flags,
			     MBX_E_MALFORMED, 0, 1),
		PAYLOAD_CASE("raw frame len 9", MBX_CMD_RAW_SEND, sizeof raw_len9, MBX_E_PARAM, 0,
			     1),
		PAYLOAD_CASE("raw frame id 0x800 without EXT", MBX_CMD_RAW_SEND, sizeof raw_id,
			     MBX_E_PARAM, 0, 1),
		PAYLOAD_CASE("raw frame data beyond len", MBX_CMD_RAW_SEND, sizeof raw_dirty,
			     MBX_E_MALFORMED, 0, 1),
		PAYLOAD_CASE("raw send 17 bytes", MBX_CMD_RAW_SEND, 17, MBX_E_MALFORMED, 0, 1),
		PAYLOAD_CASE("raw send 33 frames", MBX_CMD_RAW_SEND, 33 * sizeof(mbx_raw_frame),
			     MBX_E_MALFORMED, 0, 1),
		PAYLOAD_CASE("store sub 0", MBX_CMD_STORE, sizeof store0, MBX_E_PARAM, 0, 1),
		PAYLOAD_CASE("PDO request 0", MBX_CMD_PDO_REQUEST, sizeof pdo0, MBX_E_PARAM, 0, 1),
		{ "NMT cs 0x03 with NO_REPLY",
		  MBX_CMD_NMT,
		  { 0 },
		  sizeof nmt_cs,
		  OFF_FLAGS,
		  1,
		  MBX_F_NO_REPLY,
		  0,
		  NO_ANSWER,
		  0,
		  1 },
	};
	const void *src[] = { &nmt_node,    &nmt_cs,    &nmt_pad,     &nmt_node,    &sdo_node0,
			      &sdo_node128, &sdo_mode9, &obj_missing, &obj_bad_sub, &obj_flags,
			      &raw_len9,    &raw_id,    &raw_dirty,   NULL,         NULL,
			      &store0,      &pdo0,      &nmt_cs };
	TEST_ASSERT_EQUAL_size_t(sizeof payload_cases / sizeof payload_cases[0],
				 sizeof src / sizeof src[0]);
	for (size_t i = 0; i < sizeof payload_cases / sizeof payload_cases[0]; i++) {
		bad_case *c = &payload_cases[i];
		if (src[i])
			memcpy(c->payload, src[i], c->plen);
		else /* valid frames (id 0x100, len 0) in a wrong-sized array */
			for (size_t off = 0; off + 4 <= c->plen; off += sizeof(mbx_raw_frame))
				put_le(c->payload + off, 4, 0x100);
		run_bad_case(c);
	}
}

/* A REGISTER naming queues that do not exist: nowhere to answer, counted
 * all the same. */
static void register_naming_missing_queues(void)
{
	mbx_stats_wire before = raw_stats();
	mbx_register_req r = { .pid = (uint32_t)getpid(), .uid = 0 };
	snprintf(r.resp_queue, sizeof r.resp_queue, "/cogw.sys5.nothere.resp");
	snprintf(r.event_queue, sizeof r.event_queue, "/cogw.sys5.nothere.evt");
	mbx_hdr h = cmd_hdr(MBX_CMD_REGISTER);
	h.client = 0;
	h.token = 0;
	uint8_t msg[1024];
	int n = mbx_msg_build(msg, sizeof msg, &h, &r, sizeof r);
	raw_send_bytes(msg, (size_t)n);
	TEST_ASSERT_EQUAL_UINT64(before.malformed + 1, raw_stats().malformed);
}

/* A burst of garbage: every message refused and counted once, the line
 * keeps serving (the queue is drained, nothing blocks). */
static void garbage_burst_counted(void)
{
	mbx_stats_wire before = raw_stats();
	uint64_t seed = 0x5eed;
	enum {
		BURST = 300
	};
	for (int i = 0; i < BURST; i++) {
		uint8_t msg[256];
		size_t n = 1 + (size_t)(i * 37 % 255);
		for (size_t k = 0; k < n; k++) {
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			msg[k] = (uint8_t)(seed >> 56);
		}
		if (n >= MBX_HDR_SIZE && (i & 1)) { /* get past magic/version */
			put_le(msg + OFF_MAGIC, 2, MBX_MAGIC);
			msg[OFF_VERSION] = MBX_VERSION;
		}
		raw_send_bytes(msg, n);
	}
	mbx_stats_wire after = raw_stats();
	TEST_ASSERT_EQUAL_UINT64(before.malformed + BURST, after.malformed);
	printf("malformed counter after the burst: %llu\n", (unsigned long long)after.malformed);
}

/* Still serving: another client's normal work, a raw frame on the bus. */
static void still_serving_after_garbage(void)
{
	open_client("sys5");
	TEST_ASSERT_EQUAL_UINT16(1000, od_read_u16(client, 0x1017));
	can_fd = can_open_raw("vcan0");
	TEST_ASSERT_GREATER_OR_EQUAL_INT(0, can_fd);
	mbx_raw_frame fr = { .id = 0x321, .len = 2, .data = { 0xAB, 0xCD } };
	TEST_ASSERT_EQUAL_INT(0, cogw_raw_send(client, 0, &fr, 1, 5000));
	uint8_t data[8];
	TEST_ASSERT_EQUAL_INT(2, can_wait_id(can_fd, 0x321, data, 5000));
	TEST_ASSERT_EQUAL_HEX8(0xAB, data[0]);
	TEST_ASSERT_EQUAL_HEX8(0xCD, data[1]);
}

static void test_malformed_messages_against_daemon(void)
{
	char json[4096];
	config_text(json, sizeof json, &(cfg_params){ .instance = "sys5", .n_lines = 2 });
	start_daemon(&d, json, "sys5", 2, 0, NULL);
	raw_open("sys5");

	malformed_header_fields();
	malformed_chunk_fields();
	malformed_payload_fields();
	register_naming_missing_queues();
	garbage_burst_counted();
	still_serving_after_garbage();

	raw_close();
	cogw_close(client);
	client = NULL;
	TEST_ASSERT_FALSE(proc_exited(d.pid, &d.exit_status));
	int st = daemon_stop(&d, 10000);
	TEST_ASSERT_TRUE(st != -1 && WIFEXITED(st));
	TEST_ASSERT_EQUAL_INT(0, WEXITSTATUS(st));
}

/* ---- 7. systemd unit ------------------------------------------------------------------- */

static void test_systemd_unit_verifies(void)
{
	if (access("/usr/bin/systemd-analyze", X_OK) != 0)
		TEST_IGNORE_MESSAGE("systemd-analyze not installed");
	make_scratch_dir();
	char cwd[512], cmd[2048], log[128];
	TEST_ASSERT_NOT_NULL(getcwd(cwd, sizeof cwd));
	snprintf(log, sizeof log, "%s/verify.log", scratch_dir);
	/* the unit as shipped, but starting the binary just built */
	snprintf(cmd, sizeof cmd,
		 "sed 's#^ExecStart=/usr/local/bin/cogwd#ExecStart=%s/build/rel/bin/cogwd#' "
		 "etc/cogwd.service > %s/cogwd.service"
		 " && grep -q '^ExecStart=%s/build/rel/bin/cogwd ' %s/cogwd.service"
		 " && SYSTEMD_LOG_LEVEL=notice systemd-analyze verify %s/cogwd.service > %s 2>&1",
		 cwd, scratch_dir, cwd, scratch_dir, scratch_dir, log);
	int rc = system(cmd);
	proc_dump_log(log, 30);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "systemd-analyze verify failed");
	/* "Unknown key name", "Unknown lvalue", "ignoring": settings this
	 * systemd does not know would silently not apply */
	TEST_ASSERT_FALSE(file_contains(log, "Unknown"));
	TEST_ASSERT_FALSE(file_contains(log, "nknown key"));
	TEST_ASSERT_FALSE(file_contains(log, "gnoring"));
	TEST_ASSERT_FALSE(file_contains(log, "is not executable"));
}

/* Under the shipped unit's capability set a non-root
 * client could not register (without CAP_DAC_OVERRIDE the root daemon
 * cannot open a 0600 queue of another user, so REGISTER went unanswered).
 * The daemon runs here with exactly the unit's CapabilityBoundingSet
 * (setpriv --bounding-set) and a client of uid 65534 must be served. */
static void test_unit_capabilities_serve_a_non_root_client(void)
{
	if (access("/usr/bin/setpriv", X_OK) != 0)
		TEST_IGNORE_MESSAGE("setpriv not installed");
	char bset[512];
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_unit_bounding_set(bset, sizeof bset),
				      "no CapabilityBoundingSet in etc/cogwd.service");
	printf("daemon under %s\n", bset);
	const char *const wrapper[] = { "/usr/bin/setpriv", bset, NULL };
	char json[4096];
	cfg_params p = { .instance = "sys1c",
			 .n_lines = 1,
			 .mailbox = "\"queue_mode\": \"0622\", \"default_access\": \"read\", ",
			 .line0 = RELOAD_OBJ };
	config_text(json, sizeof json, &p);
	int rc = daemon_start(&d, &(daemon_opts){ .config_json = json,
						  .instance = "sys1c",
						  .n_lines = 1,
						  .notify = true,
						  .wrapper = wrapper });
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "cogwd did not come up under the unit's capabilities");
	start_child("sys1c");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, child_do('r'), "a non-root client was not served");
	TEST_ASSERT_EQUAL_INT(COGW_E_ACCESS, child_do('w')); /* read-only by default_access */
	stop_child();
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
	RUN_TEST(test_invalid_config_refused_with_path);
	RUN_TEST(test_depth_above_msg_max_refused);
	RUN_TEST(test_systemd_unit_verifies);
	RUN_TEST(test_unit_capabilities_serve_a_non_root_client);
	RUN_TEST(test_no_ready_when_a_line_fails);
	RUN_TEST(test_notify_ready_status_watchdog_stall_stopping);
	RUN_TEST(test_watchdog_check_period_fits_the_watchdog);
	RUN_TEST(test_special_files_do_not_block);
	RUN_TEST(test_memory_locked_by_need_and_reported);
	RUN_TEST(test_transfers_never_acknowledged_and_the_memory_budget);
	RUN_TEST(test_client_survives_a_daemon_kill_and_restart);
	RUN_TEST(test_store_restore_survives_restart);
	RUN_TEST(test_store_takes_effect_at_reset);
	RUN_TEST(test_restore_takes_effect_at_reset);
	RUN_TEST(test_sighup_reload);
	RUN_TEST(test_malformed_messages_against_daemon);
	return UNITY_END();
}
