/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_client_loop.c - libcogw's loop handle
 * (cogw_loop_*, docs/mailbox.md "Event loops") against the real cogwd on
 * vcan0, driven by a poll() loop in this process:
 *
 *  - many requests in flight and raw-frame events at once: every request
 *    answered exactly once, by correlation id, with the right value;
 *    every frame sent on the bus arrives as an event (or is counted as
 *    dropped); chunked commands and chunked answers (a 20 KiB DOMAIN
 *    written and read back through the loop); the descriptor is not
 *    readable once everything was taken; no thread was ever created
 *    (/proc/self/task);
 *  - the lease (1.5 s) kept by cogw_loop_tick alone over 4.5 s of idling;
 *  - the daemon stopped (SIGSTOP): sends end in COGW_E_WOULDBLOCK and the
 *    line's command queue is not writable; continued, it becomes writable
 *    and every request sent is answered;
 *  - the daemon killed (SIGKILL) under the loop: every request in flight
 *    gets exactly one answer (its own or COGW_E_TIMEOUT), nothing hangs;
 *    a new daemon: the handle notices, registers and subscribes again by
 *    itself, requests are answered and events come again.
 *
 *   make build/san/tests/integration/test_client_loop build/san/bin/cogwd
 *   tests/vcan/run -n 1 -- build/san/tests/integration/test_client_loop
 */
#include <dirent.h>
#include <errno.h>
#include <linux/can.h>
#include <net/if.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"
#include "unity.h"

#define INSTANCE "itloop"
#define BLOB 0x2200
#define BLOB_SIZE (20u * 1024u)
#define RAW_ID 0x321u

/* One line; a short lease (the loop's tick must renew it), a shallow
 * command queue (so that a stopped daemon fills it), a DOMAIN for chunks. */
static const char config_json[] =
	"{\n"
	" \"version\": 1,\n"
	" \"mailbox\": {\"instance\": \"" INSTANCE "\", \"depth\": 16, \"msg_size\": 1024,\n"
	"             \"lease_ms\": 1500},\n"
	" \"lines\": [\n"
	"  {\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": "
	"127,\n"
	"   \"objects\": [{\"index\": \"0x2200\", \"name\": \"blob\", \"type\": \"DOMAIN\",\n"
	"                \"access\": \"rw\", \"max_size\": 65536}]}\n"
	" ]\n"
	"}\n";

static daemon_run dmn;
static cogw *h;
static int can_fd = -1;

static int thread_count(void)
{
	DIR *d = opendir("/proc/self/task");
	int n = 0;

	TEST_ASSERT_NOT_NULL(d);
	for (struct dirent *e; (e = readdir(d));)
		n += e->d_name[0] != '.';
	closedir(d);
	return n;
}

static int can_open(const char *ifname)
{
	struct sockaddr_can a = { .can_family = AF_CAN };
	struct ifreq ifr = { 0 };
	int s = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);

	TEST_ASSERT_TRUE(s >= 0);
	snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
	TEST_ASSERT_EQUAL_INT(0, ioctl(s, SIOCGIFINDEX, &ifr));
	a.can_ifindex = ifr.ifr_ifindex;
	TEST_ASSERT_EQUAL_INT(0, bind(s, (struct sockaddr *)&a, sizeof a));
	return s;
}

static void start_daemon(void)
{
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = config_json,
								    .instance = INSTANCE,
								    .n_lines = 1 }));
}

void setUp(void)
{
	start_daemon();
	can_fd = can_open("vcan0");
	TEST_ASSERT_EQUAL_INT(
		0, cogw_loop_open(&h, &(cogw_options){ .instance = INSTANCE, .event_depth = 64 }));
	TEST_ASSERT_EQUAL_INT(0, cogw_loop_attach(h, 0, 10000));
	TEST_ASSERT_TRUE(cogw_loop_fd(h) >= 0);
}

void tearDown(void)
{
	cogw_close(h);
	h = NULL;
	if (can_fd >= 0)
		close(can_fd);
	can_fd = -1;
	daemon_stop(&dmn, 10000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues(INSTANCE);
}

/* The requests of a test: each started one is answered exactly once. */
#define REQ_MAX 4096
static struct req {
	uint64_t corr;
	int status; /* 1 = not answered yet */
	uint16_t code;
} reqs[REQ_MAX];
static unsigned n_reqs, n_answered, n_events, n_dropped;
static uint8_t blob_back[BLOB_SIZE];
static size_t blob_back_len;

static void reset_counts(void)
{
	n_reqs = n_answered = n_events = n_dropped = 0;
}

static int send_req(uint16_t code, const void *p, size_t len, unsigned timeout_ms)
{
	uint64_t corr = 0;
	int rc = cogw_loop_send(h, 0, code, p, len, timeout_ms, &corr);

	if (rc == 0) {
		TEST_ASSERT_TRUE(n_reqs < REQ_MAX);
		reqs[n_reqs++] = (struct req){ .corr = corr, .status = 1, .code = code };
	}
	return rc;
}

static int send_od_read(uint16_t index, unsigned timeout_ms)
{
	mbx_obj_req o = { .index = index, .sub = 0 };

	return send_req(MBX_CMD_OD_READ, &o, sizeof o, timeout_ms);
}

/* Take one message in: an answer is matched with its request (checked:
 * 1017h reads 1000 ms as set at start-up, the blob its pattern). */
static void take(const cogw_msg *m)
{
	if (m->kind == MBX_KIND_EVENT) {
		n_dropped += m->dropped;
		if (m->code == MBX_EV_RAW) {
			mbx_ev_raw ev;

			TEST_ASSERT_EQUAL_size_t(sizeof ev, m->len);
			memcpy(&ev, m->data, sizeof ev);
			if ((ev.frame.id & CAN_SFF_MASK) == RAW_ID)
				n_events++;
		}
		return;
	}
	for (unsigned i = 0; i < n_reqs; i++) {
		if (reqs[i].corr != m->corr)
			continue;
		TEST_ASSERT_EQUAL_INT_MESSAGE(1, reqs[i].status, "a request answered twice");
		TEST_ASSERT_EQUAL_UINT16(reqs[i].code, m->code);
		reqs[i].status = m->status;
		n_answered++;
		if (m->status == 0 && m->code == MBX_CMD_OD_READ && m->len == 2) {
			TEST_ASSERT_EQUAL_UINT8(0xE8, m->data[0]); /* 1017h = 1000 */
			TEST_ASSERT_EQUAL_UINT8(0x03, m->data[1]);
		} else if (m->status == 0 && m->code == MBX_CMD_OD_READ) {
			TEST_ASSERT_TRUE(m->len <= sizeof blob_back);
			memcpy(blob_back, m->data, m->len);
			blob_back_len = m->len;
		}
		return;
	}
	TEST_FAIL_MESSAGE("an answer with a correlation id nobody sent");
}

/* One turn of the loop: wait (at most what the library says, and
 * max_ms), tick, take in everything there is. */
static void loop_turn(int max_ms)
{
	struct pollfd pf = { .fd = cogw_loop_fd(h), .events = POLLIN };
	int t = cogw_loop_timeout_ms(h);
	cogw_msg m;
	int rc;

	TEST_ASSERT_TRUE(t >= 0);
	poll(&pf, 1, t < max_ms ? t : max_ms);
	cogw_loop_tick(h);
	while ((rc = cogw_loop_recv(h, &m)) == 0) {
		take(&m);
		cogw_msg_release(&m);
	}
	TEST_ASSERT_EQUAL_INT_MESSAGE(COGW_E_AGAIN, rc, cogw_strerror(rc));
}

static void loop_until_answered(uint64_t max_ms)
{
	uint64_t t0 = mono_ms();

	while (n_answered < n_reqs && mono_ms() - t0 < max_ms)
		loop_turn(100);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(n_reqs, n_answered, "requests left unanswered");
}

static void send_raw_frame(unsigned i)
{
	struct can_frame f = { .can_id = RAW_ID, .can_dlc = 2, .data = { (uint8_t)i, 0x5A } };

	TEST_ASSERT_EQUAL_INT((int)sizeof f, (int)write(can_fd, &f, sizeof f));
}

static void fill_blob(uint8_t *b)
{
	for (size_t i = 0; i < BLOB_SIZE; i++)
		b[i] = (uint8_t)(i * 7u + (i >> 8) + 1u);
}

static void test_many_requests_and_events_in_flight_without_a_thread(void)
{
	enum {
		TOTAL = 600,
		IN_FLIGHT = 48,
		FRAMES = 300
	};
	static uint8_t blob[sizeof(mbx_obj_req) + BLOB_SIZE];
	mbx_obj_req o = { .index = BLOB, .sub = 0 };
	unsigned frames = 0, would_block = 0;

	TEST_ASSERT_EQUAL_INT(1, thread_count());
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 0, MBX_EVC_RAW, NULL, 0, 0));
	reset_counts();
	/* a chunked command and a chunked answer through the loop */
	memcpy(blob, &o, sizeof o);
	fill_blob(blob + sizeof o);
	TEST_ASSERT_EQUAL_INT(0, send_req(MBX_CMD_OD_WRITE, blob, sizeof blob, 10000));
	loop_until_answered(15000);
	TEST_ASSERT_EQUAL_INT(0, reqs[0].status);
	TEST_ASSERT_EQUAL_INT(0, send_od_read(BLOB, 10000));
	loop_until_answered(15000);
	TEST_ASSERT_EQUAL_INT(0, reqs[1].status);
	TEST_ASSERT_EQUAL_size_t(BLOB_SIZE, blob_back_len);
	TEST_ASSERT_EQUAL_MEMORY(blob + sizeof o, blob_back, BLOB_SIZE);

	/* many reads in flight while frames arrive as events */
	uint64_t t0 = mono_ms();
	while ((n_reqs < TOTAL + 2 || n_answered < n_reqs || frames < FRAMES) &&
	       mono_ms() - t0 < 60000) {
		while (n_reqs < TOTAL + 2 && n_reqs - n_answered < IN_FLIGHT) {
			int rc = send_od_read(0x1017, 10000);

			if (rc == COGW_E_WOULDBLOCK) {
				would_block++;
				break;
			}
			TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, cogw_strerror(rc));
		}
		for (int i = 0; i < 4 && frames < FRAMES; i++)
			send_raw_frame(frames++);
		loop_turn(100);
	}
	uint64_t t_evt = mono_ms();
	while (n_events + n_dropped < FRAMES && mono_ms() - t_evt < 5000)
		loop_turn(100);
	printf("loop: %u requests answered in %llu ms (%u refused as full), %u events, "
	       "%u dropped\n",
	       n_answered, (unsigned long long)(mono_ms() - t0), would_block, n_events, n_dropped);
	TEST_ASSERT_EQUAL_UINT(TOTAL + 2, n_reqs);
	TEST_ASSERT_EQUAL_UINT(n_reqs, n_answered);
	for (unsigned i = 0; i < n_reqs; i++)
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, reqs[i].status, cogw_strerror(reqs[i].status));
	TEST_ASSERT_EQUAL_UINT(FRAMES, n_events + n_dropped);
	TEST_ASSERT_TRUE(n_events > 0);
	/* everything taken: the descriptor is quiet */
	struct pollfd pf = { .fd = cogw_loop_fd(h), .events = POLLIN };
	TEST_ASSERT_EQUAL_INT(0, poll(&pf, 1, 0));
	TEST_ASSERT_EQUAL_INT(1, thread_count());
	/* and one frame makes it readable */
	send_raw_frame(0);
	TEST_ASSERT_EQUAL_INT(1, poll(&pf, 1, 5000));
	TEST_ASSERT_EQUAL_INT(1, thread_count());
}

static void test_lease_kept_by_the_tick_alone(void)
{
	reset_counts();
	uint64_t t0 = mono_ms();
	/* three leases without a request (a lease long enough that a VM
	 * standing still under load does not lapse it) */
	while (mono_ms() - t0 < 4500)
		loop_turn(1000);
	TEST_ASSERT_EQUAL_INT(0, send_od_read(0x1017, 5000));
	loop_until_answered(6000);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reqs[0].status, cogw_strerror(reqs[0].status));
	TEST_ASSERT_EQUAL_INT(1, thread_count());
}

static void test_full_command_queue_is_a_status_and_a_writable_condition(void)
{
	int cmd = cogw_loop_cmd_fd(h, 0), rc = 0;
	unsigned sent = 0;

	TEST_ASSERT_TRUE(cmd >= 0);
	TEST_ASSERT_EQUAL_INT(COGW_E_NOT_REGISTERED, cogw_loop_cmd_fd(h, 1));
	reset_counts();
	TEST_ASSERT_EQUAL_INT(0, kill(dmn.pid, SIGSTOP));
	int st; /* every thread of it stopped: nothing reads its queue any more */
	TEST_ASSERT_EQUAL_INT(dmn.pid, waitpid(dmn.pid, &st, WUNTRACED));
	TEST_ASSERT_TRUE(WIFSTOPPED(st));
	while (sent < 200 && (rc = send_od_read(0x1017, 30000)) == 0)
		sent++;
	printf("stopped daemon: %u commands queued, then %s\n", sent, cogw_strerror(rc));
	TEST_ASSERT_EQUAL_INT(COGW_E_WOULDBLOCK, rc);
	TEST_ASSERT_TRUE(sent > 0 && sent < 200);
	struct pollfd pf = { .fd = cmd, .events = POLLOUT };
	TEST_ASSERT_EQUAL_INT(0, poll(&pf, 1, 200));
	TEST_ASSERT_EQUAL_INT(COGW_E_WOULDBLOCK, send_od_read(0x1017, 30000));
	TEST_ASSERT_EQUAL_INT(0, kill(dmn.pid, SIGCONT));
	TEST_ASSERT_EQUAL_INT(1, poll(&pf, 1, 10000));
	TEST_ASSERT_TRUE(pf.revents & POLLOUT);
	loop_until_answered(20000);
	for (unsigned i = 0; i < n_reqs; i++)
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, reqs[i].status, cogw_strerror(reqs[i].status));
	TEST_ASSERT_EQUAL_INT(0, send_od_read(0x1017, 5000));
	loop_until_answered(6000);
	TEST_ASSERT_EQUAL_INT(1, thread_count());
}

static void test_daemon_killed_under_the_loop_and_replaced(void)
{
	int status, rc;

	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 0, MBX_EVC_RAW, NULL, 0, 0));
	reset_counts();
	for (int i = 0; i < 12; i++)
		TEST_ASSERT_EQUAL_INT(0, send_od_read(0x1017, 1500));
	TEST_ASSERT_EQUAL_INT(0, kill(dmn.pid, SIGKILL));
	TEST_ASSERT_EQUAL_INT(dmn.pid, waitpid(dmn.pid, &status, 0));
	dmn.pid = 0;
	/* more after its death: they go into its queue, nobody reads them */
	unsigned after = 0;
	for (int i = 0; i < 4; i++) {
		rc = send_od_read(0x1017, 1500);
		TEST_ASSERT_TRUE_MESSAGE(rc == 0 || rc == COGW_E_WOULDBLOCK, cogw_strerror(rc));
		after += rc == 0;
	}
	uint64_t t0 = mono_ms();
	loop_until_answered(5000);
	unsigned timed_out = 0;
	for (unsigned i = 0; i < n_reqs; i++) {
		TEST_ASSERT_TRUE_MESSAGE(reqs[i].status == 0 || reqs[i].status == COGW_E_TIMEOUT,
					 cogw_strerror(reqs[i].status));
		timed_out += reqs[i].status == COGW_E_TIMEOUT;
	}
	printf("killed daemon: %u requests, %u timed out, all answered within %llu ms\n", n_reqs,
	       timed_out, (unsigned long long)(mono_ms() - t0));
	TEST_ASSERT_TRUE(after > 0 && timed_out >= after);

	/* a successor: the loop notices it (the queue's name is another
	 * queue), fails what went to the old one with COGW_E_RESTARTED,
	 * registers and subscribes again by itself */
	daemon_cleanup(&dmn);
	start_daemon();
	reset_counts();
	t0 = mono_ms();
	unsigned refused = 0, served = 0;
	while (!served && mono_ms() - t0 < 15000) {
		if (n_answered == n_reqs) {
			rc = send_od_read(0x1017, 3000);
			TEST_ASSERT_TRUE_MESSAGE(rc == 0 || rc == COGW_E_WOULDBLOCK ||
							 rc == COGW_E_NO_DAEMON,
						 cogw_strerror(rc));
			refused += rc != 0;
		}
		loop_turn(100);
		for (unsigned i = 0; i < n_reqs; i++) {
			TEST_ASSERT_TRUE_MESSAGE(reqs[i].status <= 1 ||
							 reqs[i].status == COGW_E_RESTARTED ||
							 reqs[i].status == COGW_E_TIMEOUT,
						 cogw_strerror(reqs[i].status));
			served += reqs[i].status == 0;
		}
	}
	printf("new daemon: served again %llu ms after its start (%u requests before, %u sends "
	       "refused)\n",
	       (unsigned long long)(mono_ms() - t0), n_reqs - 1, refused);
	TEST_ASSERT_TRUE_MESSAGE(served, "not served by the new daemon");
	t0 = mono_ms();
	for (unsigned i = 0; n_events == 0 && mono_ms() - t0 < 5000; i++) {
		send_raw_frame(i);
		loop_turn(100);
	}
	TEST_ASSERT_TRUE_MESSAGE(n_events > 0, "no event after the re-registration");
	TEST_ASSERT_EQUAL_INT(1, thread_count());
}

static void test_daemon_stopped_cleanly_under_the_loop(void)
{
	reset_counts();
	for (int i = 0; i < 8; i++)
		TEST_ASSERT_EQUAL_INT(0, send_od_read(0x1017, 20000));
	uint64_t t0 = mono_ms();
	TEST_ASSERT_TRUE(daemon_stop(&dmn, 10000) != -1);
	/* its queue is gone: what it did not answer is COGW_E_RESTARTED
	 * within a tick's restart watch, long before the time-out */
	loop_until_answered(5000);
	for (unsigned i = 0; i < n_reqs; i++)
		TEST_ASSERT_TRUE_MESSAGE(reqs[i].status == 0 ||
						 reqs[i].status == COGW_E_RESTARTED ||
						 reqs[i].status == COGW_E_SHUTDOWN,
					 cogw_strerror(reqs[i].status));
	printf("stopped daemon: its %u requests answered within %llu ms\n", n_reqs,
	       (unsigned long long)(mono_ms() - t0));
	uint64_t t1 = mono_ms();
	int rc = 0;
	while (mono_ms() - t1 < 3000 && (rc = send_od_read(0x1017, 1000)) != COGW_E_NO_DAEMON)
		loop_turn(100);
	TEST_ASSERT_EQUAL_INT_MESSAGE(COGW_E_NO_DAEMON, rc, cogw_strerror(rc));
	TEST_ASSERT_EQUAL_INT(1, thread_count());
}

static void test_loop_calls_refuse_a_helper_thread_handle(void)
{
	cogw *plain = NULL;
	cogw_msg m;

	TEST_ASSERT_EQUAL_INT(0, cogw_open(&plain, INSTANCE));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_loop_fd(plain));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_loop_recv(plain, &m));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL,
			      cogw_loop_send(plain, 0, MBX_CMD_OD_READ, NULL, 0, 0, NULL));
	cogw_close(plain);
	/* a line never attached, a command the mailbox answers itself */
	mbx_obj_req o = { .index = 0x1017 };
	TEST_ASSERT_EQUAL_INT(COGW_E_NOT_REGISTERED,
			      cogw_loop_send(h, 1, MBX_CMD_OD_READ, &o, sizeof o, 0, NULL));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_loop_send(h, 0, MBX_CMD_PING, NULL, 0, 0, NULL));
	/* cogw_recv works on a loop handle, waiting in the loop's way */
	TEST_ASSERT_EQUAL_INT(COGW_E_AGAIN, cogw_recv(h, &m, 50));
	TEST_ASSERT_EQUAL_INT(0, cogw_ping(h, 0, 0));
	TEST_ASSERT_EQUAL_INT(1, thread_count());
}

#define RUN(fn)                                               \
	do {                                                  \
		const char *only_ = getenv("COGW_TEST_ONLY"); \
		if (!only_ || strstr(#fn, only_))             \
			RUN_TEST(fn);                         \
	} while (0)

int main(void)
{
	signal(SIGPIPE, SIG_IGN);
	UNITY_BEGIN();
	RUN(test_many_requests_and_events_in_flight_without_a_thread);
	RUN(test_lease_kept_by_the_tick_alone);
	RUN(test_full_command_queue_is_a_status_and_a_writable_condition);
	RUN(test_daemon_killed_under_the_loop_and_replaced);
	RUN(test_daemon_stopped_cleanly_under_the_loop);
	RUN(test_loop_calls_refuse_a_helper_thread_handle);
	return UNITY_END();
}
