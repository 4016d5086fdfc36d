/* SPDX-License-Identifier: MIT */
/*
 * The application watchdog, the hold on the own node's OPERATIONAL and
 * host ready / not ready in the real daemon on vcan (docs/application.md):
 *   - an essential client (`cogwctl app 0 essential`) killed with SIGKILL:
 *     the safe-output TPDO, the EMCY 6200h golden frame and the NMT stop
 *     of all nodes on the bus, the watchdog-timeout event naming its pid;
 *   - one stopped with SIGSTOP: the EMCY and the heartbeat stop; resumed
 *     with SIGCONT it learns of the trip, declares again (--rearm), and the
 *     EMCY error reset and the heartbeat come back;
 *   - every NMT reaction (pre-operational, reset communication, reset
 *     node) and the safe outputs alone, from a client of the test; on a
 *     line without NMT master the NMT reaction is reported unavailable and
 *     nothing is sent;
 *   - a read-only client (uid 65534) can neither declare nor keep alive;
 *   - host not ready: safe outputs, NMT stop, the own node pre-operational,
 *     requests for the line's nodes refused; ready starts them again;
 *   - a holder keeps the own node out of OPERATIONAL; its start is
 *     deferred and applied when the holder says ready.
 * The delays of the frames after the missed deadline are printed as
 * figures (make bench measures them: bench_vcan_mailbox); the assertion
 * is only "within the interval, a line tick and a generous margin".
 * Run: tests/vcan/run -n 2 -- build/san/tests/integration/test_app_watchdog
 */
#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/sockios.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "core/manager.h"
#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define INSTANCE "appwdt"
#define OWN 127
#define EMCY_COB (0x80 + OWN)
#define HB_COB (0x700 + OWN)
#define TPDO_COB 0x1FF
/* generous: a loaded VM; the figures say what it really is */
#define MARGIN_MS 1500

/* Line 0: the manager (NMT master), 2000h mapped by TPDO 1 (1FFh,
 * event-driven), its safe value 0; heartbeat 100 ms. Line 1: no manager. */
#define CONFIG                                                                                  \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"" INSTANCE "\", \"queue_mode\": "       \
	"\"0622\", \"rules\": [{\"uid\": 65534, \"access\": \"read\"}]}, \"lines\": ["          \
	"{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, "                   \
	" \"heartbeat_ms\": 100, \"tpdos\": 1, \"manager\": {}, \"nodes\": [],"                 \
	" \"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED16\", \"access\": \"rwr\"," \
	"   \"default\": 500}],"                                                                \
	" \"values\": [{\"index\": \"0x1800\", \"sub\": 1, \"value\": 511},"                    \
	"   {\"index\": \"0x1800\", \"sub\": 2, \"value\": 254},"                               \
	"   {\"index\": \"0x1A00\", \"sub\": 0, \"value\": 1},"                                 \
	"   {\"index\": \"0x1A00\", \"sub\": 1, \"value\": 536870928}],"                        \
	" \"app\": {\"watchdog_reactions\": [\"emcy\", \"safe-outputs\"],"                      \
	"   \"safe_outputs\": [{\"index\": \"0x2000\", \"value\": 0}]}},"                       \
	"{\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, "                   \
	" \"heartbeat_ms\": 0}]}"

static daemon_run dmn;
static cogw *h;
static int fd0 = -1, fd1 = -1;
static pid_t child;
static char child_log[DAEMON_PATH_MAX];

/* ---- frames with their kernel time ---------------------------------------- */

typedef struct seen_frame {
	uint32_t id;
	uint8_t len;
	uint8_t data[8];
	uint64_t mono_us; /* the kernel's receive time, on CLOCK_MONOTONIC */
} seen_frame;

#define FRAMES_MAX 4096
static seen_frame frames[FRAMES_MAX];
static size_t n_frames;

static uint64_t clock_us(clockid_t id)
{
	struct timespec ts;
	clock_gettime(id, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void drain(int fd)
{
	struct can_frame f;
	struct pollfd p = { .fd = fd, .events = POLLIN };
	while (poll(&p, 1, 0) > 0 && read(fd, &f, sizeof f) > 0)
		;
	n_frames = 0;
}

/* Read frames of fd into frames[] for ms (SIOCGSTAMP is CLOCK_REALTIME:
 * moved onto the monotonic clock with the offset read now). */
static void collect(int fd, int ms)
{
	uint64_t until = mono_ms() + (uint64_t)ms;
	int64_t offset = (int64_t)clock_us(CLOCK_REALTIME) - (int64_t)clock_us(CLOCK_MONOTONIC);
	while (mono_ms() < until && n_frames < FRAMES_MAX) {
		struct pollfd p = { .fd = fd, .events = POLLIN };
		struct can_frame f;
		struct timeval tv;
		if (poll(&p, 1, 20) <= 0 || read(fd, &f, sizeof f) != (ssize_t)sizeof f)
			continue;
		seen_frame *s = &frames[n_frames++];
		s->id = f.can_id;
		s->len = f.len;
		memcpy(s->data, f.data, 8);
		s->mono_us = ioctl(fd, SIOCGSTAMP, &tv) == 0
				     ? (uint64_t)((int64_t)tv.tv_sec * 1000000 + tv.tv_usec -
						  offset)
				     : clock_us(CLOCK_MONOTONIC);
	}
}

/* The first frame with this id (and these leading bytes) from index `from`. */
static const seen_frame *find_frame(uint32_t id, const uint8_t *data, uint8_t n)
{
	for (size_t i = 0; i < n_frames; i++)
		if (frames[i].id == id && (!n || !memcmp(frames[i].data, data, n)))
			return &frames[i];
	return NULL;
}

static unsigned count_frames(uint32_t id)
{
	unsigned k = 0;
	for (size_t i = 0; i < n_frames; i++)
		k += frames[i].id == id;
	return k;
}

/* ---- the daemon and its clients --------------------------------------------- */

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	h = NULL;
	child = 0;
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = CONFIG,
								    .instance = INSTANCE,
								    .n_lines = 2 }));
	snprintf(child_log, sizeof child_log, "%s/client.log", dmn.dir);
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, INSTANCE));
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 0, MBX_EVC_APP, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 1, MBX_EVC_APP, NULL, 0, 3000));
	fd0 = can_open_raw("vcan0");
	fd1 = can_open_raw("vcan1");
	TEST_ASSERT_TRUE(fd0 >= 0 && fd1 >= 0);
	/* every frame stamped at its reception (else SIOCGSTAMP stamps the
	 * first one read with the time of the read) */
	int on = 1;
	TEST_ASSERT_EQUAL_INT(0, setsockopt(fd0, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on));
	TEST_ASSERT_EQUAL_INT(0, setsockopt(fd1, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on));
}

void tearDown(void)
{
	if (child > 0) {
		kill(child, SIGCONT);
		proc_stop(child, SIGKILL, 2000);
	}
	if (fd0 >= 0)
		close(fd0);
	if (fd1 >= 0)
		close(fd1);
	fd0 = fd1 = -1;
	if (h)
		cogw_close(h);
	daemon_cleanup(&dmn);
	daemon_unlink_queues(INSTANCE);
}

static uint8_t own_state(unsigned line)
{
	mbx_line_status st;
	TEST_ASSERT_EQUAL_INT(0, cogw_line_status(h, line, &st, 3000));
	return st.nmt_state;
}

static void wait_own_state(unsigned line, uint8_t state, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	while (own_state(line) != state) {
		if (mono_ms() > until)
			TEST_FAIL_MESSAGE("the own node did not reach the NMT state in time");
		sleep_ms(20);
	}
}

/* The entry of pid in line 0's status, waiting for it to be in `state`. */
static mbx_appwd_entry wait_entry(pid_t pid, uint8_t state, int timeout_ms)
{
	mbx_appwd_status st;
	mbx_appwd_entry wd[MBX_APPWD_MAX];
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		int n = cogw_app_status(h, 0, &st, wd, MBX_APPWD_MAX, 3000);
		TEST_ASSERT_TRUE(n >= 0);
		for (int i = 0; i < n; i++)
			if (wd[i].pid == (uint32_t)pid && wd[i].state == state)
				return wd[i];
		if (mono_ms() > until) {
			proc_dump_log(child_log, 20);
			TEST_FAIL_MESSAGE("no watchdog entry in that state");
		}
		sleep_ms(20);
	}
}

static pid_t spawn_essential(const char *interval, const char *react, bool rearm)
{
	const char *argv[] = { "build/san/bin/cogwctl",
			       "--instance",
			       INSTANCE,
			       "app",
			       "0",
			       "essential",
			       "--interval",
			       interval,
			       "--react",
			       react,
			       rearm ? "--rearm" : NULL,
			       NULL };
	pid_t pid = proc_spawn(argv, child_log, NULL);
	TEST_ASSERT_TRUE(pid > 0);
	return pid;
}

/* The next event of this code on this line. */
static void wait_event(unsigned line, uint16_t code, void *out, size_t len, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	cogw_msg m;
	while (mono_ms() < until) {
		if (cogw_recv(h, &m, 100) != 0)
			continue;
		bool hit = m.kind == MBX_KIND_EVENT && m.line == line && m.code == code &&
			   m.len == len;
		if (hit)
			memcpy(out, m.data, len);
		cogw_msg_release(&m);
		if (hit)
			return;
	}
	TEST_FAIL_MESSAGE("event not received");
}

static void expect_frame_after(const char *what, uint32_t id, const uint8_t *data, uint8_t n,
			       uint64_t deadline_us)
{
	const seen_frame *f = find_frame(id, data, n);
	char msg[96];
	snprintf(msg, sizeof msg, "%s not seen on the bus", what);
	TEST_ASSERT_NOT_NULL_MESSAGE(f, msg);
	int64_t delay = (int64_t)f->mono_us - (int64_t)deadline_us;
	printf("figure: %s on the bus %lld us after the deadline\n", what, (long long)delay);
	TEST_ASSERT_TRUE_MESSAGE(delay > -5000, "a reaction before the deadline");
	TEST_ASSERT_TRUE_MESSAGE(delay < MARGIN_MS * 1000, "a reaction far after the deadline");
}

/* ---- SIGKILL, SIGSTOP ------------------------------------------------------------ */

static const uint8_t emcy_6200[8] = { 0x00, 0x62, 0x81, 0, 0, 0, 0, 0 };
static const uint8_t emcy_reset[8] = { 0, 0, 0, 0, 0, 0, 0, 0 };
static const uint8_t tpdo_safe[2] = { 0x00, 0x00 };

static void test_sigkill_fires_safe_outputs_emcy_and_nmt_stop(void)
{
	static const uint8_t nmt_stop[2] = { 0x02, 0x00 };
	mbx_ev_appwd ev;

	wait_own_state(0, 0x05, 10000);
	child = spawn_essential("500", "emcy,nmt-stop,safe-outputs", false);
	wait_entry(child, 2 /* armed */, 5000);
	drain(fd0);
	uint64_t killed_us = clock_us(CLOCK_MONOTONIC);
	kill(child, SIGKILL);
	wait_event(0, MBX_EV_APP_WD_TIMEOUT, &ev, sizeof ev, 500 + MARGIN_MS);
	collect(fd0, 300);
	TEST_ASSERT_EQUAL_UINT32((uint32_t)child, ev.pid);
	TEST_ASSERT_EQUAL_UINT32(500, ev.interval_ms);
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_EMCY | MBX_APPWD_R_NMT_STOP | MBX_APPWD_R_SAFE_OUTPUTS,
				ev.reactions);
	TEST_ASSERT_EQUAL_HEX32(ev.reactions, ev.done);
	TEST_ASSERT_EQUAL_UINT32(1, ev.trips);
	printf("figure: SIGKILL: the line ran the reactions %u us after the deadline, "
	       "%lld ms after the kill\n",
	       ev.late_us, (long long)(ev.deadline_us + ev.late_us - killed_us) / 1000);
	TEST_ASSERT_TRUE(ev.deadline_us + ev.late_us - killed_us < (500 + MARGIN_MS) * 1000u);
	expect_frame_after("safe-output TPDO 1FFh [00 00]", TPDO_COB, tpdo_safe, 2, ev.deadline_us);
	expect_frame_after("EMCY 6200h", EMCY_COB, emcy_6200, 8, ev.deadline_us);
	expect_frame_after("NMT stop all", 0x000, nmt_stop, 2, ev.deadline_us);
	/* the outputs first, then the EMCY, then the network */
	TEST_ASSERT_TRUE(find_frame(TPDO_COB, tpdo_safe, 2) < find_frame(EMCY_COB, NULL, 0));
	TEST_ASSERT_TRUE(find_frame(EMCY_COB, NULL, 0) < find_frame(0x000, nmt_stop, 2));
	uint16_t v = 1;
	size_t len = 0;
	TEST_ASSERT_EQUAL_INT(0, cogw_od_read(h, 0, 0x2000, 0, &v, sizeof v, &len, 3000, NULL));
	TEST_ASSERT_EQUAL_UINT16(0, v);
	proc_stop(child, SIGKILL, 1000);
	child = 0;
	TEST_ASSERT_TRUE(file_wait_contains(dmn.log_path, "application watchdog: client", 2000));
}

static void test_sigstop_fires_then_the_client_comes_back(void)
{
	mbx_ev_appwd ev;

	wait_own_state(0, 0x05, 10000);
	child = spawn_essential("400", "emcy,hb-stop", true);
	wait_entry(child, 2, 5000);
	drain(fd0);
	kill(child, SIGSTOP);
	wait_event(0, MBX_EV_APP_WD_TIMEOUT, &ev, sizeof ev, 400 + MARGIN_MS);
	TEST_ASSERT_EQUAL_UINT32((uint32_t)child, ev.pid);
	TEST_ASSERT_EQUAL_UINT8(0, ev.gone); /* stopped, not gone: its lease is alive */
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_EMCY | MBX_APPWD_R_HB_STOP, ev.done);
	collect(fd0, 500);
	expect_frame_after("EMCY 6200h (SIGSTOP)", EMCY_COB, emcy_6200, 8, ev.deadline_us);
	/* no heartbeat later than the reaction plus one frame's time */
	const seen_frame *e = find_frame(EMCY_COB, emcy_6200, 8);
	for (size_t i = 0; i < n_frames; i++)
		if (frames[i].id == HB_COB)
			TEST_ASSERT_TRUE_MESSAGE(frames[i].mono_us < e->mono_us + 2000,
						 "a heartbeat after the watchdog stopped it");
	wait_entry(child, 3 /* tripped */, 1000);
	/* back: its next keep-alive hears of the trip, it declares again,
	 * which acknowledges: the EMCY error reset, the heartbeat again */
	drain(fd0);
	kill(child, SIGCONT);
	TEST_ASSERT_TRUE(file_wait_contains(child_log, "declaring again", 3000));
	collect(fd0, 600);
	TEST_ASSERT_NOT_NULL_MESSAGE(find_frame(EMCY_COB, emcy_reset, 8), "no EMCY error reset");
	TEST_ASSERT_TRUE(count_frames(HB_COB) >= 3);
	mbx_appwd_entry w = wait_entry(child, 2, 2000);
	TEST_ASSERT_EQUAL_UINT32(400, w.interval_ms);
	proc_stop(child, SIGTERM, 3000);
	child = 0;
}

/* ---- every reaction, from a client of the test ------------------------------------ */

/* Declare on line, one keep-alive, then silence: the trip's event. */
static void trip_once(unsigned line, uint32_t reactions, mbx_appwd_resp *resp, mbx_ev_appwd *ev)
{
	TEST_ASSERT_EQUAL_INT(0, cogw_app_watchdog(h, line, 50, reactions, resp, 3000));
	drain(line ? fd1 : fd0);
	TEST_ASSERT_EQUAL_INT(0, cogw_app_keepalive(h, line, 3000));
	wait_event(line, MBX_EV_APP_WD_TIMEOUT, ev, sizeof *ev, 50 + MARGIN_MS);
	collect(line ? fd1 : fd0, 200);
	/* a keep-alive after the trip is refused until declared again */
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE, cogw_app_keepalive(h, line, 3000));
}

static void test_every_nmt_reaction_and_the_safe_outputs(void)
{
	static const struct {
		uint32_t reaction;
		uint8_t cs;
		const char *name;
	} nmt[] = { { MBX_APPWD_R_NMT_PREOP, 0x80, "NMT pre-operational all" },
		    { MBX_APPWD_R_NMT_RESET_COMM, 0x82, "NMT reset communication all" },
		    { MBX_APPWD_R_NMT_RESET_NODE, 0x81, "NMT reset node all" } };
	mbx_appwd_resp resp;
	mbx_ev_appwd ev;

	wait_own_state(0, 0x05, 10000);
	TEST_ASSERT_EQUAL_INT(COGW_E_NOT_FOUND, cogw_app_keepalive(h, 0, 3000));
	/* cogwctl monitor shows the trips of the app class */
	const char *mon[] = { "build/san/bin/cogwctl",
			      "--instance",
			      INSTANCE,
			      "monitor",
			      "--line",
			      "0",
			      "--class",
			      "app",
			      NULL };
	child = proc_spawn(mon, child_log, NULL);
	TEST_ASSERT_TRUE(file_wait_contains(child_log, "watching app events", 5000));
	for (unsigned i = 0; i < sizeof nmt / sizeof nmt[0]; i++) {
		uint8_t frame[2] = { nmt[i].cs, 0 };
		trip_once(0, nmt[i].reaction, &resp, &ev);
		TEST_ASSERT_EQUAL_HEX32(0, resp.unavailable);
		TEST_ASSERT_EQUAL_HEX32(nmt[i].reaction, ev.done);
		expect_frame_after(nmt[i].name, 0x000, frame, 2, ev.deadline_us);
		wait_own_state(0, 0x05, 10000); /* the manager boots and starts again */
	}
	TEST_ASSERT_TRUE(file_wait_contains(child_log, "missed its 50 ms keep-alive", 3000));
	TEST_ASSERT_TRUE(file_contains(child_log, "nmt-reset-node"));
	proc_stop(child, SIGTERM, 3000);
	child = 0;
	TEST_ASSERT_EQUAL_INT(0, cogw_od_write(h, 0, 0x2000, 0, &(uint16_t){ 700 }, 2, 3000, NULL));
	trip_once(0, MBX_APPWD_R_SAFE_OUTPUTS, &resp, &ev);
	expect_frame_after("safe-output TPDO 1FFh", TPDO_COB, tpdo_safe, 2, ev.deadline_us);
	/* the line's configured set */
	trip_once(0, MBX_APPWD_R_CONFIGURED, &resp, &ev);
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_EMCY | MBX_APPWD_R_SAFE_OUTPUTS, resp.reactions);
	expect_frame_after("EMCY 6200h (configured)", EMCY_COB, emcy_6200, 8, ev.deadline_us);
	/* withdrawing acknowledges too */
	drain(fd0);
	TEST_ASSERT_EQUAL_INT(0, cogw_app_watchdog(h, 0, 0, 0, NULL, 3000));
	collect(fd0, 200);
	TEST_ASSERT_NOT_NULL(find_frame(EMCY_COB, emcy_reset, 8));
	TEST_ASSERT_EQUAL_INT(COGW_E_NOT_FOUND, cogw_app_watchdog(h, 0, 0, 0, NULL, 3000));

	/* line 1 has no NMT master and no safe outputs: said at once, skipped */
	trip_once(1, MBX_APPWD_R_NMT_STOP | MBX_APPWD_R_EMCY, &resp, &ev);
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_NMT_STOP, resp.unavailable);
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_EMCY, ev.done);
	TEST_ASSERT_EQUAL_UINT(0, count_frames(0x000));
	TEST_ASSERT_EQUAL_INT(COGW_E_UNSUPPORTED,
			      cogw_app_watchdog(h, 1, 50, MBX_APPWD_R_CONFIGURED, NULL, 3000));
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM,
			      cogw_app_watchdog(h, 1, 50,
						MBX_APPWD_R_NMT_STOP | MBX_APPWD_R_NMT_PREOP, NULL,
						3000));
}

/* ---- read-only ---------------------------------------------------------------------- */

/* cogwctl as uid 65534 ("read" in the rules); its exit status. */
static int cogwctl_as_nobody(const char *const args[])
{
	const char *argv[16] = { "build/san/bin/cogwctl", "--instance", INSTANCE };
	size_t n = 3;
	for (; args[n - 3] && n < 15; n++)
		argv[n] = args[n - 3];
	argv[n] = NULL;
	pid_t pid = fork();
	if (pid == 0) {
		int fd = open(child_log, O_WRONLY | O_APPEND | O_CREAT, 0666);
		if (fd >= 0) {
			dup2(fd, 1);
			dup2(fd, 2);
		}
		if (setgid(65534) || setuid(65534))
			_exit(99);
		execv(argv[0], (char *const *)argv);
		_exit(98);
	}
	int st = 0;
	waitpid(pid, &st, 0);
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void test_read_only_client_cannot_arm(void)
{
	static const char *const essential[] = { "app", "0",       "essential",     "--interval",
						 "20",  "--react", "emcy,nmt-stop", NULL };
	static const char *const show[] = { "app", "0", NULL };
	mbx_appwd_status st;

	TEST_ASSERT_EQUAL_INT(1, cogwctl_as_nobody(essential)); /* refused */
	TEST_ASSERT_TRUE(file_contains(child_log, "access"));
	TEST_ASSERT_EQUAL_INT(0, cogwctl_as_nobody(show)); /* may look */
	TEST_ASSERT_EQUAL_INT(0, cogw_app_status(h, 0, &st, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_UINT64(0, st.declared);
	TEST_ASSERT_EQUAL_UINT64(0, st.trips);
	drain(fd0);
	collect(fd0, 300); /* its silence fires nothing */
	TEST_ASSERT_NULL(find_frame(EMCY_COB, emcy_6200, 8));
}

/* ---- host not ready / ready, the hold ------------------------------------------------ */

static void test_host_not_ready_then_ready(void)
{
	static const uint8_t nmt_stop[2] = { 0x02, 0x00 };
	mbx_ev_host ev;
	uint8_t buf[4];
	size_t len;

	wait_own_state(0, 0x05, 10000);
	drain(fd0);
	TEST_ASSERT_EQUAL_INT(0, cogw_host_ready(h, 0, 0, 3000));
	wait_event(0, MBX_EV_HOST_STATE, &ev, sizeof ev, 2000);
	TEST_ASSERT_EQUAL_UINT8(0, ev.ready);
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_SAFE_OUTPUTS | MBX_APPWD_R_NMT_STOP, ev.done);
	collect(fd0, 400);
	TEST_ASSERT_NOT_NULL(find_frame(TPDO_COB, tpdo_safe, 2));
	TEST_ASSERT_NOT_NULL(find_frame(0x000, nmt_stop, 2));
	TEST_ASSERT_EQUAL_HEX8(0x7F, own_state(0));
	mbx_mgr_status ms;
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &ms, 3000));
	TEST_ASSERT_EQUAL_UINT8(CO_MGR_STOPPED, ms.state); /* the manager holds the network */
	TEST_ASSERT_NOT_NULL_MESSAGE(find_frame(HB_COB, &(uint8_t){ 0x7F }, 1),
				     "the own heartbeat does not say pre-operational");
	/* requests for the line's nodes and its safe outputs: STATE */
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE,
			      cogw_sdo_read(h, 0, 5, 0x1000, 0, buf, sizeof buf, &len, 3000, NULL));
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE, cogw_nmt(h, 0, 0x01, 0, 3000));
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE,
			      cogw_od_write(h, 0, 0x2000, 0, &(uint16_t){ 9 }, 2, 3000, NULL));
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE, cogw_mgr_start(h, 0, 3000));
	/* its own objects still answer */
	TEST_ASSERT_EQUAL_INT(0, cogw_od_read(h, 0, 0x1017, 0, buf, sizeof buf, &len, 3000, NULL));
	/* a start of the own node is deferred */
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE, cogw_nmt(h, 0, 0x01, OWN, 3000));

	drain(fd0);
	TEST_ASSERT_EQUAL_INT(0, cogw_host_ready(h, 0, 1, 3000));
	wait_event(0, MBX_EV_HOST_STATE, &ev, sizeof ev, 2000);
	TEST_ASSERT_EQUAL_UINT8(1, ev.ready);
	wait_own_state(0, 0x05, 3000);
	/* the manager started the network (it has no slaves: no frame) */
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &ms, 3000));
	TEST_ASSERT_EQUAL_UINT8(CO_MGR_OPERATIONAL, ms.state);
	mbx_appwd_status st;
	TEST_ASSERT_EQUAL_INT(0, cogw_app_status(h, 0, &st, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_UINT64(1, st.not_ready_episodes);
	TEST_ASSERT_TRUE(st.host_ready);
}

static void test_hold_defers_the_own_start(void)
{
	const char *argv[] = {
		"build/san/bin/cogwctl", "--instance", INSTANCE, "app", "0", "hold", NULL
	};
	mbx_appwd_nmt ev;

	wait_own_state(0, 0x05, 10000);
	TEST_ASSERT_EQUAL_INT(0, cogw_nmt(h, 0, 0x80, OWN, 3000));
	wait_own_state(0, 0x7F, 2000);
	child = proc_spawn(argv, child_log, NULL);
	TEST_ASSERT_TRUE(file_wait_contains(child_log, "holding", 5000));
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE, cogw_nmt(h, 0, 0x01, OWN, 3000));
	for (;;) { /* the refusal's event (state changes of the pre-op came first) */
		wait_event(0, MBX_EV_APP_NMT, &ev, sizeof ev, 2000);
		if (ev.flags & MBX_APPWD_NMT_REFUSED)
			break;
	}
	TEST_ASSERT_EQUAL_HEX8(0x7F, ev.state);
	TEST_ASSERT_EQUAL_UINT8(1, ev.holders);
	TEST_ASSERT_TRUE(ev.flags & MBX_APPWD_NMT_DEFERRED);
	sleep_ms(300);
	TEST_ASSERT_EQUAL_HEX8(0x7F, own_state(0));
	/* ready: the deferred start applies */
	proc_stop(child, SIGTERM, 3000);
	child = 0;
	wait_event(0, MBX_EV_APP_NMT, &ev, sizeof ev, 2000);
	TEST_ASSERT_EQUAL_HEX8(0x05, ev.state);
	TEST_ASSERT_EQUAL_HEX8(0x01, ev.cs);
	mbx_appwd_status st;
	TEST_ASSERT_EQUAL_INT(0, cogw_app_status(h, 0, &st, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_UINT64(1, st.starts_refused);
	TEST_ASSERT_EQUAL_UINT8(0, st.holders);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_sigkill_fires_safe_outputs_emcy_and_nmt_stop);
	RUN_TEST(test_sigstop_fires_then_the_client_comes_back);
	RUN_TEST(test_every_nmt_reaction_and_the_safe_outputs);
	RUN_TEST(test_read_only_client_cannot_arm);
	RUN_TEST(test_host_not_ready_then_ready);
	RUN_TEST(test_hold_defers_the_own_start);
	return UNITY_END();
}
