/* SPDX-License-Identifier: MIT */
/*
 * libcogw's leader/follower reading under ThreadSanitizer (build/tsan): an
 * in-process mbx_server on a loop thread (as a line thread drives it) with
 * real POSIX message queues, and one libcogw handle shared by several
 * threads at once:
 * - callers whose answers come at once (OD read: each caller reads its own
 *   sub-index and checks the value names it), so that usually one of them
 *   reads its own answer as the leader;
 * - callers whose answers come later and out of order (index 3000h: held
 *   by the fake line for 0..3 loop turns), so that a leader receives the
 *   answers of the others and hands them over;
 * - one thread sending asynchronously and collecting with cogw_recv()
 *   while the callers run, so that the helper thread and the callers take
 *   turns at leading;
 * - one thread waiting for events with cogw_recv() (the line publishes an
 *   EMCY every few turns), which waits on the event queue itself while no
 *   asynchronous answer is due and is woken when one becomes due; both
 *   receiving threads take whatever comes, events or answers;
 * - the helper thread starts only with the subscription, the first
 *   asynchronous request or receive, or a caller's wait longer than one
 *   slice, while the callers already lead without it, so it joins a handle
 *   in use.
 * Checked: no data race (TSan fails the run on one), every answer reaches
 * exactly the thread that asked with its own value, every asynchronous
 * answer arrives once, events arrive, and no answer is left over as stray.
 *
 * And loop handles (cogw_loop_*), one per thread as event loops use them,
 * each thread polling its handle's descriptor, with answers held back and
 * overtaking each other and events coming: no data race between them (the
 * library keeps no state across handles), every answer once and right.
 */
#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "unity.h"

#include "mailbox/cogw.h"
#include "mailbox/server.h"

#define LINE 0
#define CALLERS 4
#define LATE_CALLERS 2
#define CALLS 300
#define ASYNCS 200
#define HELD_MAX 64

typedef struct held {
	mbx_reply_to to;
	uint8_t sub;
	unsigned turns;
} held;

static mbx_server *srv;
static pthread_t loop_thr;
static atomic_bool stop;
static held hold[HELD_MAX];
static unsigned n_held;
static uint64_t rng = 1;
static char instance[32], qname[MBX_QNAME_MAX];
static cogw *handle;
static atomic_uint wrong, failed;

static uint64_t now_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void answer(mbx_server *s, const mbx_reply_to *to, uint16_t index, uint8_t sub)
{
	uint8_t v[4] = { (uint8_t)index, (uint8_t)(index >> 8), sub, 0xA5 };

	mbx_server_respond(s, to, 0, 0, v, sizeof v);
}

static void fake_dispatch(void *ctx, mbx_server *s, const mbx_request *req)
{
	mbx_obj_req o;

	(void)ctx;
	if (req->code != MBX_CMD_OD_READ) {
		mbx_server_respond(s, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
		return;
	}
	memcpy(&o, req->payload, sizeof o);
	if (o.index == 0x3000 && n_held < HELD_MAX) {
		rng = rng * 6364136223846793005ull + 1442695040888963407ull;
		hold[n_held++] = (held){ .to = req->reply, .sub = o.sub, .turns = (rng >> 60) & 3 };
		return;
	}
	answer(s, &req->reply, o.index, o.sub);
}

/* The held answers whose turn came, in the order they are found: later
 * requests overtake earlier ones. */
static void release_held(void)
{
	for (unsigned i = 0; i < n_held;) {
		if (hold[i].turns--) {
			i++;
			continue;
		}
		answer(srv, &hold[i].to, 0x3000, hold[i].sub);
		hold[i] = hold[--n_held];
	}
}

static void *loop_main(void *arg)
{
	(void)arg;
	mbx_ev_emcy e = { .node = 5, .code = 0x8130 };

	for (unsigned turn = 0; !atomic_load(&stop); turn++) {
		struct pollfd pf = { .fd = mbx_server_fd(srv), .events = POLLIN };

		poll(&pf, 1, 1);
		uint64_t now = now_us();

		mbx_server_poll(srv, now);
		release_held();
		if (turn % 8 == 0)
			mbx_server_publish(srv, MBX_EV_EMCY, 0, &e, sizeof e);
		mbx_server_tick(srv, now);
	}
	return NULL;
}

static void *caller(void *arg)
{
	unsigned id = (unsigned)(uintptr_t)arg;
	uint16_t index = id >= CALLERS ? 0x3000 : 0x2000;

	for (unsigned i = 0; i < CALLS; i++) {
		uint8_t v[4] = { 0 };
		size_t len = 0;
		int rc = cogw_od_read(handle, LINE, index, (uint8_t)id, v, sizeof v, &len, 20000,
				      NULL);

		if (rc != 0) {
			fprintf(stderr, "caller %u, call %u: %s\n", id, i, cogw_strerror(rc));
			atomic_fetch_add(&failed, 1);
		} else if (len != 4 || v[0] != (uint8_t)index || v[1] != index >> 8 || v[2] != id ||
			   v[3] != 0xA5)
			atomic_fetch_add(&wrong, 1);
	}
	return NULL;
}

static atomic_uint async_answers, events;
static atomic_bool asyncs_done;

/* One message from cogw_recv (either receiving thread): an event or an
 * asynchronous answer, checked. */
static bool take_one(int timeout_ms)
{
	cogw_msg m;

	if (cogw_recv(handle, &m, timeout_ms) != 0)
		return false;
	if (m.kind == MBX_KIND_EVENT && (m.code == MBX_EV_EMCY || m.code == MBX_EV_OVERFLOW))
		atomic_fetch_add(&events, 1); /* a slow turn under TSan may overflow the queue */
	else if (m.kind == MBX_KIND_RESPONSE && m.status == 0 && m.len == 4 && m.data[2] == 0xEE)
		atomic_fetch_add(&async_answers, 1);
	else {
		fprintf(stderr, "unexpected: kind %u code %04X status %d len %zu\n",
			(unsigned)m.kind, (unsigned)m.code, m.status, m.len);
		atomic_fetch_add(&wrong, 1);
	}
	cogw_msg_release(&m);
	return true;
}

/* At most 4 in flight (the server answers BUSY past its per-client limit),
 * until ASYNCS were answered, or 20 s passed without a message. */
static void *async_user(void *arg)
{
	mbx_obj_req r = { .index = 0x2000, .sub = 0xEE };
	unsigned sent = 0;
	uint64_t since = now_us();

	(void)arg;
	/* subscribed while the callers already run, before the asynchronous
	 * requests: at most CALLERS + LATE_CALLERS + 4 answers are due at once,
	 * which the response queue holds (fs.mqueue.msg_max is 10 by default) */
	if (cogw_subscribe(handle, LINE, MBX_EVC_EMCY, NULL, 0, 20000) != 0)
		atomic_fetch_add(&failed, 1);
	while (atomic_load(&async_answers) < ASYNCS) {
		uint64_t corr;

		while (sent - atomic_load(&async_answers) < 4 && sent < ASYNCS) {
			if (cogw_send_async(handle, LINE, MBX_CMD_OD_READ, &r, sizeof r, &corr) !=
			    0)
				break;
			sent++;
		}
		if (take_one(100)) {
			since = now_us();
		} else if (now_us() - since > 20000000u) {
			atomic_fetch_add(&failed, 1);
			break;
		}
	}
	atomic_store(&asyncs_done, true);
	return NULL;
}

/* Its first cogw_recv() (or the other thread's subscription) starts the
 * helper thread while the callers already lead without it. */
static void *event_user(void *arg)
{
	(void)arg;
	while (!atomic_load(&asyncs_done))
		take_one(50);
	return NULL;
}

void setUp(void)
{
	atomic_store(&stop, false);
	n_held = 0;
	snprintf(instance, sizeof instance, "ts%d", (int)getpid());
	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(qname, sizeof qname, instance, LINE));
	mbx_server_config cfg = {
		.line = LINE,
		.queue_name = qname,
		.queue_mode = 0600,
		.depth = 10,
		.msg_size = 1024,
		.max_clients = 4,
		.check_ms = 100,
		.xfer_slots = 4,
		.max_transfer = 64 * 1024,
		.default_access = MBX_ACCESS_WRITE,
		.unlink_existing = true,
		.dispatch = { .dispatch = fake_dispatch },
	};
	int rc = mbx_server_create(&srv, &cfg);

	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, strerror(-rc));
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&loop_thr, NULL, loop_main, NULL));
}

void tearDown(void)
{
	atomic_store(&stop, true);
	pthread_join(loop_thr, NULL);
	mbx_server_destroy(srv);
}

static void test_threads_share_one_handle(void)
{
	pthread_t t[CALLERS + LATE_CALLERS + 2];
	cogw_stats st;

	TEST_ASSERT_EQUAL_INT(0, cogw_open(&handle, instance));
	for (unsigned i = 0; i < CALLERS + LATE_CALLERS; i++)
		TEST_ASSERT_EQUAL_INT(0, pthread_create(&t[i], NULL, caller, (void *)(uintptr_t)i));
	TEST_ASSERT_EQUAL_INT(0,
			      pthread_create(&t[CALLERS + LATE_CALLERS], NULL, async_user, NULL));
	TEST_ASSERT_EQUAL_INT(
		0, pthread_create(&t[CALLERS + LATE_CALLERS + 1], NULL, event_user, NULL));
	for (unsigned i = 0; i < CALLERS + LATE_CALLERS + 2; i++)
		pthread_join(t[i], NULL);
	cogw_get_stats(handle, &st);
	cogw_close(handle);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, atomic_load(&failed), "calls failed");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, atomic_load(&wrong), "answers reached the wrong caller");
	TEST_ASSERT_EQUAL_UINT(ASYNCS, atomic_load(&async_answers));
	TEST_ASSERT_TRUE_MESSAGE(atomic_load(&events) > 0, "no event arrived");
	TEST_ASSERT_EQUAL_UINT64(0, st.stray_responses);
	TEST_ASSERT_EQUAL_UINT64(0, st.async_dropped);
}

#define LOOPS 3
#define LOOP_READS 300

/* One event loop on its own loop handle: up to 4 reads under way (the
 * server's per-client limit), half of them held back by the fake line;
 * each answer checked by the sub-index that names this loop. */
static void *loop_user(void *arg)
{
	unsigned id = (unsigned)(uintptr_t)arg;
	unsigned sent = 0, answered = 0, evts = 0;
	uint64_t since = now_us();
	cogw *h = NULL;

	if (cogw_loop_open(&h, &(cogw_options){ .instance = instance }) != 0 ||
	    cogw_loop_attach(h, LINE, 20000) != 0 ||
	    cogw_subscribe(h, LINE, MBX_EVC_EMCY, NULL, 0, 20000) != 0) {
		atomic_fetch_add(&failed, 1);
		cogw_close(h);
		return NULL;
	}
	while (answered < LOOP_READS && now_us() - since < 20000000u) {
		while (sent - answered < 4 && sent < LOOP_READS) {
			mbx_obj_req r = { .index = sent % 2 ? 0x3000 : 0x2000,
					  .sub = (uint8_t)(0x40 + id) };

			if (cogw_loop_send(h, LINE, MBX_CMD_OD_READ, &r, sizeof r, 20000, NULL) !=
			    0)
				break;
			sent++;
		}
		struct pollfd pf = { .fd = cogw_loop_fd(h), .events = POLLIN };
		cogw_msg m;

		poll(&pf, 1, cogw_loop_timeout_ms(h));
		cogw_loop_tick(h);
		while (cogw_loop_recv(h, &m) == 0) {
			if (m.kind == MBX_KIND_EVENT) {
				evts++;
			} else if (m.status == 0 && m.len == 4 && m.data[2] == 0x40 + id) {
				answered++;
				since = now_us();
			} else {
				fprintf(stderr, "loop %u: status %d len %zu\n", id, m.status,
					m.len);
				atomic_fetch_add(&wrong, 1);
				answered++;
			}
			cogw_msg_release(&m);
		}
	}
	if (answered != LOOP_READS)
		atomic_fetch_add(&failed, 1);
	atomic_fetch_add(&events, evts);
	cogw_close(h);
	return NULL;
}

static void test_loop_handles_one_per_thread(void)
{
	pthread_t t[LOOPS];

	atomic_store(&failed, 0);
	atomic_store(&wrong, 0);
	atomic_store(&events, 0);
	for (unsigned i = 0; i < LOOPS; i++)
		TEST_ASSERT_EQUAL_INT(0,
				      pthread_create(&t[i], NULL, loop_user, (void *)(uintptr_t)i));
	for (unsigned i = 0; i < LOOPS; i++)
		pthread_join(t[i], NULL);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, atomic_load(&failed), "a loop did not get every answer");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, atomic_load(&wrong), "a wrong answer");
	TEST_ASSERT_TRUE_MESSAGE(atomic_load(&events) > 0, "no event arrived");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_threads_share_one_handle);
	RUN_TEST(test_loop_handles_one_per_thread);
	return UNITY_END();
}
