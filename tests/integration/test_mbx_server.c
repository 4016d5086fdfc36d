/* The mailbox itself with REAL POSIX message queues: an in-process
 * mbx_server (driven by a loop thread, like a line thread would) with a
 * fake dispatcher standing in for the line glue, and forked client
 * processes using libcogw. Covers registration, correlation ids, chunked
 * transfers both ways, subscription filtering, concurrent clients, full
 * client queues (drop + count + flag), dead clients (killed, queue
 * unlinked, lease expired, not expired by a stall of the server), access control by queue owner, malformed
 * commands (error answer + counters + the server keeps working) and the
 * system-limit message. Queue names are pid-based; everything is unlinked
 * at the end. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "mailbox/server.h"
#include "unity.h"

#define LINE 1
#define BIG 100000u
/* Per-call timeout: generous, the suite also runs under software emulation. */
#define CALL_MS 10000

/* ---- the fake line ------------------------------------------------------------- */

typedef struct pending {
	bool used;
	mbx_reply_to to;
	uint8_t node;
	uint16_t index;
	uint8_t sub;
	uint64_t due_us;
} pending;

typedef struct fake_line {
	pthread_mutex_t mu;
	pthread_t thr;
	volatile bool stop;
	volatile bool running; /* loop_main entered: the thread is set up */
	mbx_server *srv;
	pending pend[256];
	uint8_t big[BIG];
	size_t big_len;
	unsigned writes_ok, gone;
	uint64_t rng;
} fake_line;

static fake_line fl;
static char instance[32];
static char qname[MBX_QNAME_MAX];

static uint64_t now_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void sleep_ms(unsigned ms)
{
	struct timespec ts = { ms / 1000, (long)(ms % 1000) * 1000000L };

	nanosleep(&ts, NULL);
}

static void fake_dispatch(void *ctx, mbx_server *srv, const mbx_request *req)
{
	fake_line *f = ctx;
	mbx_obj_req o;
	mbx_sdo_req s;

	switch (req->code) {
	case MBX_CMD_OD_READ:
		memcpy(&o, req->payload, sizeof o);
		if (o.index == 0x2000) {
			uint8_t v[4] = { 0x78, 0x56, 0x34, 0x12 };

			mbx_server_respond(srv, &req->reply, 0, 0, v, 4);
		} else if (o.index == 0x2001) {
			mbx_server_respond(srv, &req->reply, 0, 0, f->big, f->big_len);
		} else {
			mbx_server_respond(srv, &req->reply, MBX_E_ABORT, 0x06020000, NULL, 0);
		}
		return;
	case MBX_CMD_OD_WRITE:
		memcpy(&o, req->payload, sizeof o);
		if (o.index == 0x2001 && req->data_len <= BIG) {
			memcpy(f->big, req->data, req->data_len);
			f->big_len = req->data_len;
			f->writes_ok++;
			mbx_server_respond(srv, &req->reply, 0, 0, NULL, 0);
		} else {
			mbx_server_respond(srv, &req->reply, MBX_E_ABORT, 0x06070012, NULL, 0);
		}
		return;
	case MBX_CMD_SDO_UPLOAD:
		/* answered later, in a shuffled order, like SDO transfers on
		 * a bus that complete whenever the node answers */
		memcpy(&s, req->payload, sizeof s);
		for (unsigned i = 0; i < 256; i++) {
			pending *p = &f->pend[i];

			if (p->used)
				continue;
			f->rng = f->rng * 6364136223846793005ull + 1;
			*p = (pending){ .used = true,
					.to = req->reply,
					.node = s.node,
					.index = s.index,
					.sub = s.sub,
					.due_us = now_us() + (f->rng >> 33) % 20000 };
			return;
		}
		mbx_server_respond(srv, &req->reply, MBX_E_BUSY, 0, NULL, 0);
		return;
	case MBX_CMD_NMT:
		mbx_server_respond(srv, &req->reply, 0, 0, NULL, 0);
		return;
	default:
		mbx_server_respond(srv, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	}
}

static void fake_gone(void *ctx, mbx_server *srv, uint32_t client)
{
	(void)srv;
	(void)client;
	((fake_line *)ctx)->gone++;
}

static void run_pending(fake_line *f, uint64_t now)
{
	for (unsigned i = 0; i < 256; i++) {
		pending *p = &f->pend[i];

		if (!p->used || now < p->due_us)
			continue;
		p->used = false;
		if (p->node == 99) {
			mbx_server_respond(f->srv, &p->to, MBX_E_ABORT, 0x06020000, NULL, 0);
			continue;
		}
		uint8_t d[4] = { p->node, (uint8_t)p->index, (uint8_t)(p->index >> 8), p->sub };
		mbx_ev_sdo_done ev = {
			.size = 4, .index = p->index, .sub = p->sub, .node = p->node, .upload = 1
		};

		mbx_server_notify(f->srv, &p->to, MBX_EV_SDO_DONE, &ev, sizeof ev);
		mbx_server_respond(f->srv, &p->to, 0, 0, d, 4);
	}
}

static void *loop_main(void *arg)
{
	fake_line *f = arg;

	f->running = true;
	while (!f->stop) {
		struct pollfd pf = { .fd = mbx_server_fd(f->srv), .events = POLLIN };

		poll(&pf, 1, 2);
		pthread_mutex_lock(&f->mu);
		uint64_t now = now_us();

		mbx_server_poll(f->srv, now);
		run_pending(f, now);
		mbx_server_tick(f->srv, now);
		pthread_mutex_unlock(&f->mu);
	}
	return NULL;
}

static mbx_server_config base_cfg(void)
{
	return (mbx_server_config){
		.line = LINE,
		.queue_name = qname,
		.queue_mode = 0622,
		.depth = 10, /* works even where msg_max is the default 10 */
		.msg_size = 1024,
		.max_clients = 8,
		.check_ms = 100,
		.xfer_slots = 4,
		.max_transfer = 256 * 1024,
		.default_access = MBX_ACCESS_WRITE,
		.unlink_existing = true,
		.dispatch = { .dispatch = fake_dispatch, .client_gone = fake_gone },
		.dispatch_ctx = &fl,
	};
}

static void start(const mbx_server_config *cfg)
{
	int rc;

	memset(fl.pend, 0, sizeof fl.pend);
	fl.stop = false;
	fl.running = false;
	fl.writes_ok = fl.gone = 0;
	fl.big_len = BIG;
	for (unsigned i = 0; i < BIG; i++)
		fl.big[i] = (uint8_t)(i * 7 + (i >> 8));
	rc = mbx_server_create(&fl.srv, cfg);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, strerror(-rc));
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&fl.thr, NULL, loop_main, &fl));
	/* No fork (spawn) before the new thread is through its start-up,
	 * see spawn(). */
	for (unsigned i = 0; i < 10000 && !fl.running; i++)
		sleep_ms(1);
	TEST_ASSERT_TRUE_MESSAGE(fl.running, "loop thread did not start");
}

static void stop(void)
{
	if (!fl.srv)
		return;
	fl.stop = true;
	pthread_join(fl.thr, NULL);
	mbx_server_destroy(fl.srv);
	fl.srv = NULL;
}

static mbx_server_stats stats(void)
{
	mbx_server_stats st;

	pthread_mutex_lock(&fl.mu);
	st = *mbx_server_stats_get(fl.srv);
	pthread_mutex_unlock(&fl.mu);
	return st;
}

/* Wait until cond(stats) holds or ms pass. */
#define WAIT_FOR(expr, ms)                                            \
	do {                                                          \
		for (unsigned w_ = 0; w_ < (ms) / 5 && !(expr); w_++) \
			sleep_ms(5);                                  \
	} while (0)

void setUp(void)
{
	snprintf(instance, sizeof instance, "t%d", (int)getpid());
	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(qname, sizeof qname, instance, LINE));
	fl.srv = NULL;
}

void tearDown(void)
{
	stop();
	mq_unlink(qname);
}

/* ---- children --------------------------------------------------------------------- */

/* Children report failures as the line number in the exit code (0 = ok):
 * Unity's assertions must not run in a forked child. */
#define CHECK(c)                                                                          \
	do {                                                                              \
		if (!(c)) {                                                               \
			fprintf(stderr, "child %d: %s:%d: %s\n", (int)getpid(), __FILE__, \
				__LINE__, #c);                                            \
			return __LINE__ % 250 + 1;                                        \
		}                                                                         \
	} while (0)

typedef int (*child_fn)(void *arg);

/* The child of fork() gets a copy of every lock as it was, but only the
 * forking thread: a lock another thread held at that moment stays held
 * for ever in the child. The children here go on to malloc and
 * pthread_create (libcogw), so no other thread of this process may be
 * inside the allocator or the thread registry (ASan's are not made
 * fork-safe the way glibc's malloc is) when we fork: the loop thread is
 * past its start-up (start() waits for that) and is held off its work by
 * fl.mu, so it can only be in poll() or waiting for fl.mu. Without this
 * the first child, forked while the just-created loop thread was still
 * starting, could hang in its own reader thread (slow emulation made
 * that window wide). */
static pid_t spawn(child_fn fn, void *arg)
{
	pid_t pid;

	fflush(stdout);
	pthread_mutex_lock(&fl.mu);
	pid = fork();
	pthread_mutex_unlock(&fl.mu); /* parent, and the child's copy */
	TEST_ASSERT_TRUE(pid >= 0);
	if (pid == 0)
		_exit(fn(arg));
	return pid;
}

static int reap(pid_t pid)
{
	int st = 0;

	TEST_ASSERT_EQUAL_INT(pid, waitpid(pid, &st, 0));
	if (WIFSIGNALED(st))
		return 1000 + WTERMSIG(st);
	return WEXITSTATUS(st);
}

/* A pipe pair for "ready" (child -> parent) and "go" (parent -> child). */
typedef struct sync2 {
	int ready[2], go[2];
	unsigned param;
} sync2;

static void sync_init(sync2 *s)
{
	TEST_ASSERT_EQUAL_INT(0, pipe(s->ready));
	TEST_ASSERT_EQUAL_INT(0, pipe(s->go));
}

static void sync_close(sync2 *s)
{
	close(s->ready[0]);
	close(s->ready[1]);
	close(s->go[0]);
	close(s->go[1]);
}

static void child_ready(sync2 *s)
{
	char c = 'r';

	if (write(s->ready[1], &c, 1) != 1)
		_exit(99);
}

static void child_wait_go(sync2 *s)
{
	char c;

	if (read(s->go[0], &c, 1) != 1)
		_exit(98);
}

static void parent_wait_ready(sync2 *s)
{
	struct pollfd pf = { .fd = s->ready[0], .events = POLLIN };
	char c;

	TEST_ASSERT_EQUAL_INT_MESSAGE(1, poll(&pf, 1, 10000), "child not ready");
	TEST_ASSERT_EQUAL_INT(1, read(s->ready[0], &c, 1));
}

static void parent_go(sync2 *s)
{
	char c = 'g';

	TEST_ASSERT_EQUAL_INT(1, write(s->go[1], &c, 1));
}

/* ---- tests ------------------------------------------------------------------------ */

static int child_basic(void *arg)
{
	cogw *h;
	uint8_t v[8];
	size_t len = 0;
	uint32_t abort = 0;
	uint64_t c1, c2;
	cogw_msg m;
	mbx_obj_req o = { .index = 0x2000 };

	(void)arg;
	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_od_read(h, LINE, 0x2000, 0, v, sizeof v, &len, CALL_MS, &abort) == 0);
	CHECK(len == 4 && v[0] == 0x78 && v[3] == 0x12);
	/* local OD refusal: abort code surfaces */
	CHECK(cogw_od_read(h, LINE, 0x3000, 0, v, sizeof v, &len, CALL_MS, &abort) == COGW_E_ABORT);
	CHECK(abort == 0x06020000);
	/* asynchronous: correlation ids echoed */
	CHECK(cogw_send_async(h, LINE, MBX_CMD_OD_READ, &o, sizeof o, &c1) == 0);
	CHECK(cogw_send_async(h, LINE, MBX_CMD_OD_READ, &o, sizeof o, &c2) == 0);
	CHECK(c1 != c2);
	for (int i = 0; i < 2; i++) {
		CHECK(cogw_recv(h, &m, CALL_MS) == 0);
		CHECK(m.kind == MBX_KIND_RESPONSE && m.code == MBX_CMD_OD_READ);
		CHECK(m.corr == (i == 0 ? c1 : c2));
		CHECK(m.status == 0 && m.len == 4 && m.data[0] == 0x78);
		CHECK(m.line == LINE);
		cogw_msg_release(&m);
	}
	CHECK(cogw_recv(h, &m, 0) == COGW_E_AGAIN);
	/* the service the fake line does not implement */
	CHECK(cogw_emcy_send(h, LINE, 0x1000, 1, NULL, CALL_MS) == COGW_E_UNSUPPORTED);
	/* NMT, and an SDO read with its abort code */
	CHECK(cogw_nmt(h, LINE, 0x01, 0, CALL_MS) == 0);
	CHECK(cogw_sdo_read(h, LINE, 99, 0x1018, 1, v, sizeof v, &len, CALL_MS, &abort) ==
	      COGW_E_ABORT);
	CHECK(abort == 0x06020000);
	uint32_t u32;

	CHECK(cogw_sdo_read_u32(h, LINE, 5, 0x1018, 2, &u32, CALL_MS, &abort) == 0);
	CHECK(u32 == (5u | 0x18u << 8 | 0x10u << 16 | 2u << 24));
	uint16_t u16; /* 4 bytes come back: type/length mismatch */

	CHECK(cogw_sdo_read_u16(h, LINE, 5, 0x1018, 2, &u16, CALL_MS, &abort) == COGW_E_ABORT);
	CHECK(abort == 0x06070010);
	/* a line without a daemon */
	CHECK(cogw_ping(h, 7, 500) == COGW_E_NO_DAEMON);
	mbx_stats_wire ms;

	CHECK(cogw_mbx_stats(h, LINE, &ms, CALL_MS) == 0);
	CHECK(ms.clients == 1 && ms.clients_registered == 1);
	cogw_close(h);
	return 0;
}

static void test_register_call_and_correlation(void)
{
	mbx_server_config cfg = base_cfg();

	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_basic, NULL)));
	WAIT_FOR(stats().clients == 0, 5000);
	mbx_server_stats st = stats();

	TEST_ASSERT_EQUAL_UINT64(1, st.clients_registered);
	TEST_ASSERT_EQUAL_UINT64(1, st.clients_unregistered); /* cogw_close */
	TEST_ASSERT_EQUAL_UINT64(0, st.clients_reaped);
	TEST_ASSERT_EQUAL_UINT64(0, st.malformed_total);
	TEST_ASSERT_EQUAL_UINT32(0, st.clients);
	TEST_ASSERT_TRUE(st.commands_ok >= 11);
	TEST_ASSERT_EQUAL_UINT(1, fl.gone);
}

static int child_big(void *arg)
{
	cogw *h;
	static uint8_t out[BIG], in[BIG + 10];
	size_t len = 0;
	uint32_t abort = 0;

	(void)arg;
	for (unsigned i = 0; i < BIG; i++)
		out[i] = (uint8_t)(i * 13 + 1);
	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_od_write(h, LINE, 0x2001, 0, out, BIG, 5000, &abort) == 0);
	CHECK(cogw_od_read(h, LINE, 0x2001, 0, in, sizeof in, &len, 5000, &abort) == 0);
	CHECK(len == BIG);
	CHECK(memcmp(in, out, BIG) == 0);
	/* buffer too small: truncated, full size told */
	CHECK(cogw_od_read(h, LINE, 0x2001, 0, in, 1000, &len, 5000, &abort) == COGW_E_TRUNCATED);
	CHECK(len == BIG && memcmp(in, out, 1000) == 0);
	/* larger than the line's max_transfer (256 KiB) */
	uint8_t *huge = calloc(1, 300 * 1024);

	CHECK(huge);
	CHECK(cogw_od_write(h, LINE, 0x2001, 0, huge, 300 * 1024, 5000, &abort) == COGW_E_TOO_BIG);
	free(huge);
	cogw_close(h);
	return 0;
}

static void test_chunked_transfers_both_ways(void)
{
	mbx_server_config cfg = base_cfg();

	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_big, NULL)));
	mbx_server_stats st = stats();

	TEST_ASSERT_EQUAL_UINT(1, fl.writes_ok);
	TEST_ASSERT_EQUAL_UINT64(1, st.xfer_in);
	TEST_ASSERT_EQUAL_UINT64(2, st.xfer_out);
	TEST_ASSERT_EQUAL_UINT64(0, st.xfer_failed);
	TEST_ASSERT_EQUAL_UINT64(0, st.dropped);
	for (unsigned i = 0; i < BIG; i++)
		TEST_ASSERT_EQUAL_HEX8((uint8_t)(i * 13 + 1), fl.big[i]);
}

/* subscribe to param's classes, then count what arrives */
static int child_sub(void *arg)
{
	sync2 *s = arg;
	cogw *h;
	cogw_msg m;
	unsigned hb = 0, other = 0;

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_subscribe(h, LINE, s->param, NULL, 0, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s);
	while (cogw_recv(h, &m, 300) == 0) {
		CHECK(m.kind == MBX_KIND_EVENT);
		if (mbx_event_class_of(m.code) & s->param)
			hb++;
		else
			other++;
		if (m.code == MBX_EV_HB_LOST) {
			mbx_ev_node n;

			CHECK(m.len == sizeof n);
			memcpy(&n, m.data, sizeof n);
			CHECK(n.node == 9);
			CHECK(m.corr == 0);
		}
		cogw_msg_release(&m);
	}
	CHECK(other == 0);
	CHECK(hb == (s->param == MBX_EVC_HB ? 2 : 1));
	/* unsubscribe: nothing more */
	CHECK(cogw_unsubscribe(h, LINE, s->param, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s);
	CHECK(cogw_recv(h, &m, 300) == COGW_E_AGAIN);
	cogw_close(h);
	return 0;
}

static void publish_mix(void)
{
	mbx_ev_node n = { .node = 9, .state = 0x7F };
	mbx_ev_emcy e = { .node = 9, .code = 0x8130 };
	mbx_ev_raw r = { .frame = { .id = 0x181, .len = 1 } };

	pthread_mutex_lock(&fl.mu);
	mbx_server_publish(fl.srv, MBX_EV_HB_STARTED, 0, &n, sizeof n);
	mbx_server_publish(fl.srv, MBX_EV_NMT_STATE, 0, &n, sizeof n);
	mbx_server_publish(fl.srv, MBX_EV_EMCY, 0, &e, sizeof e);
	mbx_server_publish(fl.srv, MBX_EV_BOOTUP, 0, &n, sizeof n);
	mbx_server_publish(fl.srv, MBX_EV_RAW, 0, &r, sizeof r);
	mbx_server_publish(fl.srv, MBX_EV_HB_LOST, 0, &n, sizeof n);
	pthread_mutex_unlock(&fl.mu);
}

static void test_subscription_filtering_and_unsubscribe(void)
{
	mbx_server_config cfg = base_cfg();
	sync2 a, b;
	pid_t pa, pb;

	start(&cfg);
	sync_init(&a);
	sync_init(&b);
	a.param = MBX_EVC_HB;
	b.param = MBX_EVC_EMCY;
	pa = spawn(child_sub, &a);
	pb = spawn(child_sub, &b);
	parent_wait_ready(&a);
	parent_wait_ready(&b);
	/* the class index the publishing goes by: one subscriber each */
	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_UINT(1, mbx_server_subscribers(fl.srv, MBX_EVC_HB));
	TEST_ASSERT_EQUAL_UINT(1, mbx_server_subscribers(fl.srv, MBX_EVC_EMCY));
	TEST_ASSERT_EQUAL_UINT(0, mbx_server_subscribers(fl.srv, MBX_EVC_RAW));
	pthread_mutex_unlock(&fl.mu);
	publish_mix();
	parent_go(&a);
	parent_go(&b);
	parent_wait_ready(&a);
	parent_wait_ready(&b);
	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_UINT(0, mbx_server_subscribers(fl.srv, MBX_EVC_HB));
	TEST_ASSERT_EQUAL_UINT(0, mbx_server_subscribers(fl.srv, MBX_EVC_EMCY));
	pthread_mutex_unlock(&fl.mu);
	publish_mix();
	parent_go(&a);
	parent_go(&b);
	TEST_ASSERT_EQUAL_INT(0, reap(pa));
	TEST_ASSERT_EQUAL_INT(0, reap(pb));
	sync_close(&a);
	sync_close(&b);
	/* first round: 2 HB to a, 1 EMCY to b; second round nothing */
	TEST_ASSERT_EQUAL_UINT64(3, stats().events_sent);
	TEST_ASSERT_EQUAL_UINT64(0, stats().dropped);
}

typedef struct sdo_thread_arg {
	cogw *h;
	uint8_t node;
	int fail;
} sdo_thread_arg;

static void *sdo_thread(void *p)
{
	sdo_thread_arg *a = p;

	for (unsigned i = 0; i < 40 && !a->fail; i++) {
		uint8_t d[8];
		size_t len = 0;
		uint32_t abort = 1;
		uint16_t index = (uint16_t)(0x2000 + i);
		uint8_t sub = (uint8_t)(a->node * 2 + (i & 1));

		if (cogw_sdo_read(a->h, LINE, a->node, index, sub, d, sizeof d, &len, 5000,
				  &abort) != 0 ||
		    len != 4 || abort != 0 || d[0] != a->node || d[1] != (uint8_t)index ||
		    d[2] != (uint8_t)(index >> 8) || d[3] != sub)
			a->fail = (int)i + 1;
	}
	return NULL;
}

/* two threads of one process, each on its own node */
static int child_sdo(void *arg)
{
	unsigned base = *(unsigned *)arg;
	cogw *h;
	pthread_t t[2];
	sdo_thread_arg ta[2];

	CHECK(cogw_open(&h, instance) == 0);
	for (int i = 0; i < 2; i++) {
		ta[i] = (sdo_thread_arg){ .h = h, .node = (uint8_t)(base + i) };
		CHECK(pthread_create(&t[i], NULL, sdo_thread, &ta[i]) == 0);
	}
	for (int i = 0; i < 2; i++)
		pthread_join(t[i], NULL);
	CHECK(ta[0].fail == 0);
	CHECK(ta[1].fail == 0);
	cogw_close(h);
	return 0;
}

static void test_three_clients_get_exactly_their_answers(void)
{
	mbx_server_config cfg = base_cfg();
	unsigned base[3] = { 10, 20, 30 };
	pid_t p[3];

	start(&cfg);
	for (int i = 0; i < 3; i++)
		p[i] = spawn(child_sdo, &base[i]);
	for (int i = 0; i < 3; i++)
		TEST_ASSERT_EQUAL_INT(0, reap(p[i]));
	mbx_server_stats st = stats();

	TEST_ASSERT_EQUAL_UINT64(3, st.clients_registered);
	TEST_ASSERT_EQUAL_UINT64(0, st.malformed_total);
	/* 240 answers, all delivered (the children checked each one), and
	 * 240 SDO_DONE events to their requesters, who never read their event
	 * queues: those fill up and the rest is dropped, which costs the
	 * responses nothing */
	TEST_ASSERT_TRUE(st.responses_sent >= 240 + 3);
	TEST_ASSERT_EQUAL_UINT64(240, st.events_sent + st.dropped);
	TEST_ASSERT_TRUE(st.dropped > 0);
}

static int child_slow(void *arg)
{
	sync2 *s = arg;
	cogw_options o = { .instance = instance, .event_depth = 4 };
	cogw *h;
	cogw_msg m;
	unsigned n = 0;

	CHECK(cogw_open_opts(&h, &o) == 0);
	CHECK(cogw_subscribe(h, LINE, MBX_EVC_EMCY, NULL, 0, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s); /* parent has published 10 into a queue of 4 */
	/* Exactly the 4 that fitted: as soon as one is read, the server's
	 * tick may queue the OVERFLOW notice behind them, which belongs to
	 * the next step. */
	for (; n < 4; n++) {
		CHECK(cogw_recv(h, &m, 0) == 0);
		CHECK(m.code == MBX_EV_EMCY && m.dropped == 0);
		cogw_msg_release(&m);
	}
	child_ready(s);
	child_wait_go(s); /* parent published one more */
	CHECK(cogw_recv(h, &m, CALL_MS) == 0);
	/* the first message after the loss carries the flag and count:
	 * either the overflow notice or the next EMCY */
	CHECK(m.dropped == 6);
	if (m.code == MBX_EV_OVERFLOW) {
		mbx_ev_overflow ov;

		memcpy(&ov, m.data, sizeof ov);
		CHECK(ov.dropped_events == 6 && ov.dropped_responses == 0);
	} else {
		CHECK(m.code == MBX_EV_EMCY);
	}
	cogw_msg_release(&m);
	while (cogw_recv(h, &m, 300) == 0) {
		CHECK(m.dropped == 0);
		cogw_msg_release(&m);
	}
	cogw_stats cs;

	cogw_get_stats(h, &cs);
	CHECK(cs.dropped_reported == 6);
	cogw_close(h);
	return 0;
}

static void test_full_client_queue_drops_counts_and_flags(void)
{
	mbx_server_config cfg = base_cfg();
	mbx_ev_emcy e = { .node = 3, .code = 0x8130 };
	mbx_client_info ci;
	sync2 s;
	pid_t p;
	uint64_t t0, t1;

	start(&cfg);
	sync_init(&s);
	p = spawn(child_slow, &s);
	parent_wait_ready(&s);
	pthread_mutex_lock(&fl.mu);
	t0 = now_us();
	for (int i = 0; i < 10; i++)
		mbx_server_publish(fl.srv, MBX_EV_EMCY, 0, &e, sizeof e);
	t1 = now_us();
	TEST_ASSERT_EQUAL_INT(0, mbx_server_client_info(fl.srv, 0, &ci));
	pthread_mutex_unlock(&fl.mu);
	TEST_ASSERT_TRUE_MESSAGE(t1 - t0 < 50000, "publishing blocked");
	TEST_ASSERT_EQUAL_UINT64(6, ci.dropped);
	TEST_ASSERT_EQUAL_UINT32(6, ci.pending_drop_events);
	TEST_ASSERT_EQUAL_UINT64(6, stats().dropped);
	parent_go(&s);
	parent_wait_ready(&s);
	pthread_mutex_lock(&fl.mu);
	mbx_server_publish(fl.srv, MBX_EV_EMCY, 0, &e, sizeof e);
	pthread_mutex_unlock(&fl.mu);
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT(0, reap(p));
	sync_close(&s);
	TEST_ASSERT_EQUAL_UINT64(6, stats().dropped);
}

static int child_park(void *arg)
{
	sync2 *s = arg;
	cogw *h;

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s); /* killed or told to go on */
	cogw_close(h);
	return 0;
}

static void unlink_client_queues(unsigned n)
{
	mbx_client_info ci;

	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_INT(0, mbx_server_client_info(fl.srv, n, &ci));
	pthread_mutex_unlock(&fl.mu);
	mq_unlink(ci.resp_queue);
	mq_unlink(ci.event_queue);
}

static void test_killed_client_is_reaped(void)
{
	mbx_server_config cfg = base_cfg();
	mbx_client_info ci;
	sync2 s;
	pid_t p;

	start(&cfg);
	sync_init(&s);
	p = spawn(child_park, &s);
	parent_wait_ready(&s);
	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_INT(0, mbx_server_client_info(fl.srv, 0, &ci));
	pthread_mutex_unlock(&fl.mu);
	TEST_ASSERT_EQUAL_UINT32((uint32_t)p, ci.pid);
	kill(p, SIGKILL);
	TEST_ASSERT_EQUAL_INT(1000 + SIGKILL, reap(p)); /* no zombie left */
	WAIT_FOR(stats().clients == 0, CALL_MS);
	TEST_ASSERT_EQUAL_UINT32(0, stats().clients);
	TEST_ASSERT_EQUAL_UINT64(1, stats().clients_reaped);
	TEST_ASSERT_EQUAL_UINT(1, fl.gone);
	/* a killed process leaves its queues behind: clean up */
	mq_unlink(ci.resp_queue);
	mq_unlink(ci.event_queue);
	sync_close(&s);
}

static void test_client_with_unlinked_queue_is_reaped(void)
{
	mbx_server_config cfg = base_cfg();
	sync2 s;
	pid_t p;

	start(&cfg);
	sync_init(&s);
	p = spawn(child_park, &s);
	parent_wait_ready(&s);
	unlink_client_queues(0); /* process alive, queue gone */
	WAIT_FOR(stats().clients == 0, CALL_MS);
	TEST_ASSERT_EQUAL_UINT32(0, stats().clients);
	TEST_ASSERT_EQUAL_UINT64(1, stats().clients_reaped);
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT(0, reap(p));
	sync_close(&s);
}

/* Two clients parked by child_park on a server with a 1 s lease: a goes on
 * renewing, b is what the test stops. */
typedef struct lease_pair {
	sync2 a, b;
	pid_t pa, pb;
} lease_pair;

static void lease_pair_start(lease_pair *lp)
{
	mbx_server_config cfg = base_cfg();

	cfg.lease_ms = 1000;
	start(&cfg);
	sync_init(&lp->a);
	sync_init(&lp->b);
	lp->pa = spawn(child_park, &lp->a);
	lp->pb = spawn(child_park, &lp->b);
	parent_wait_ready(&lp->a);
	parent_wait_ready(&lp->b);
	TEST_ASSERT_EQUAL_UINT32(2, stats().clients);
}

/* b (stopped) was dropped, a is the one client left; both then end. */
static void lease_pair_expect_only_a_and_end(lease_pair *lp)
{
	mbx_server_stats st = stats();
	mbx_client_info ci;

	TEST_ASSERT_EQUAL_UINT32(1, st.clients);
	TEST_ASSERT_EQUAL_UINT64(1, st.clients_reaped);
	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_INT(0, mbx_server_client_info(fl.srv, 0, &ci));
	pthread_mutex_unlock(&fl.mu);
	TEST_ASSERT_EQUAL_UINT32((uint32_t)lp->pa, ci.pid);
	parent_go(&lp->a);
	TEST_ASSERT_EQUAL_INT(0, reap(lp->pa));
	kill(lp->pb, SIGCONT);
	parent_go(&lp->b);
	TEST_ASSERT_EQUAL_INT(0, reap(lp->pb)); /* closes cleanly after all */
	sync_close(&lp->a);
	sync_close(&lp->b);
}

static void test_lease_expiry(void)
{
	lease_pair lp;

	lease_pair_start(&lp);
	kill(lp.pb, SIGSTOP); /* alive, but renews nothing */
	sleep_ms(4000);       /* > 3 leases: a keeps pinging, b expires */
	/* (a stall of this machine renews b's lapsed lease once: give it one
	 * more lease rather than fail on a slow CI host) */
	WAIT_FOR(stats().clients_reaped == 1, 2000);
	lease_pair_expect_only_a_and_end(&lp);
}

/* The whole machine stands still (a paused VM, an overloaded host): the
 * server thread and the clients stop together, and when they run again the
 * server may tick before a client's renewal has been sent. It must not
 * take that silence for the client's: lapsed leases start again once, and
 * a client that really renews nothing expires one lease later. */
static void test_late_wake_renews_lapsed_leases_once(void)
{
	lease_pair lp;

	lease_pair_start(&lp);
	kill(lp.pa, SIGSTOP);
	kill(lp.pb, SIGSTOP);
	pthread_mutex_lock(&fl.mu); /* the server thread stands still too */
	sleep_ms(1500);
	pthread_mutex_unlock(&fl.mu);
	sleep_ms(100);        /* the server runs first, */
	kill(lp.pa, SIGCONT); /* then a sends its renewal; b never does */
	sleep_ms(500);

	mbx_server_stats st = stats();

	TEST_ASSERT_EQUAL_UINT32(2, st.clients);
	TEST_ASSERT_EQUAL_UINT64(0, st.clients_reaped);
	TEST_ASSERT_EQUAL_UINT64(1, st.late_wakes);
	WAIT_FOR(stats().clients_reaped == 1, 3000);
	lease_pair_expect_only_a_and_end(&lp);
}

static int child_as_user(void *arg)
{
	unsigned uid = *(unsigned *)arg;
	cogw *h;
	uint8_t v[8];
	size_t len;
	uint32_t abort;

	CHECK(setgid(uid) == 0 && setuid(uid) == 0);
	CHECK(geteuid() == uid);
	CHECK(cogw_open(&h, instance) == 0);
	if (uid == 1001) { /* not in the rules, default NONE */
		CHECK(cogw_ping(h, LINE, 1000) == COGW_E_ACCESS);
		cogw_close(h);
		return 0;
	}
	/* read-only user: reads and subscriptions yes, writes no */
	CHECK(cogw_od_read(h, LINE, 0x2000, 0, v, sizeof v, &len, CALL_MS, &abort) == 0);
	CHECK(cogw_subscribe(h, LINE, MBX_EVC_HB, NULL, 0, CALL_MS) == 0);
	CHECK(cogw_od_write(h, LINE, 0x2001, 0, v, 4, CALL_MS, &abort) == COGW_E_ACCESS);
	CHECK(cogw_nmt(h, LINE, 0x81, 0, CALL_MS) == COGW_E_ACCESS);
	uint8_t big[5000] = { 0 }; /* chunked write: refused, rest ignored */

	CHECK(cogw_od_write(h, LINE, 0x2001, 0, big, sizeof big, CALL_MS, &abort) == COGW_E_ACCESS);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0); /* still fine afterwards */
	cogw_close(h);
	return 0;
}

static int child_open_queue(void *arg)
{
	cogw_options o = { .instance = instance, .queue_mode = 0644, .timeout_ms = 500 };
	cogw *h;

	(void)arg;
	CHECK(cogw_open_opts(&h, &o) == 0);
	/* a queue others can read would leak the token: no answer at all */
	CHECK(cogw_ping(h, LINE, 500) == COGW_E_TIMEOUT);
	cogw_close(h);
	return 0;
}

static void test_access_control_by_queue_owner(void)
{
	mbx_access_rule rules[] = { { .uid = 1000, .access = MBX_ACCESS_READ } };
	mbx_server_config cfg = base_cfg();
	unsigned u1000 = 1000, u1001 = 1001;

	if (geteuid() != 0)
		TEST_IGNORE_MESSAGE("needs root (setuid to test users)");
	cfg.rules = rules;
	cfg.n_rules = 1;
	cfg.default_access = MBX_ACCESS_NONE;
	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_as_user, &u1000)));
	mbx_server_stats st = stats();

	TEST_ASSERT_EQUAL_UINT64(3, st.access_denied);
	TEST_ASSERT_EQUAL_UINT64(1, st.clients_registered);
	TEST_ASSERT_EQUAL_UINT(0, fl.writes_ok);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_as_user, &u1001)));
	TEST_ASSERT_EQUAL_UINT64(4, stats().access_denied);
	TEST_ASSERT_EQUAL_UINT64(1, stats().clients_registered);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_open_queue, NULL)));
	TEST_ASSERT_EQUAL_UINT64(5, stats().access_denied);
	TEST_ASSERT_EQUAL_UINT64(1, stats().malformed[MBX_BAD_QUEUE]);
}

/* ---- the helper thread and the queue sizes ----------------------------------------- */

/* Threads of this process (/proc/self/status), 0 if unreadable. */
static unsigned threads_of_self(void)
{
	FILE *f = fopen("/proc/self/status", "re");
	char line[128];
	unsigned n = 0;

	while (f && fgets(line, sizeof line, f))
		if (sscanf(line, "Threads: %u", &n) == 1)
			break;
	if (f)
		fclose(f);
	return n;
}

/* The thread count reaches n within 2 s: a joined thread is counted until the
 * kernel has released it, a moment after pthread_join returned. */
static bool threads_become(unsigned n)
{
	for (int i = 0; i < 200 && threads_of_self() != n; i++)
		usleep(10000);
	return threads_of_self() == n;
}

/* A handle whose blocking calls are answered at once starts no thread; the
 * first subscription, asynchronous request or receive starts the helper
 * (restart watch, answers nobody waits for), and close ends it. */
static int child_helper_on_need(void *arg)
{
	unsigned base = threads_of_self();
	mbx_obj_req o = { .index = 0x2000 };
	uint64_t corr = 0;
	cogw_msg m;
	cogw *h;

	(void)arg;
	CHECK(base >= 1);
	CHECK(cogw_open(&h, instance) == 0);
	struct timespec t0, t1;

	clock_gettime(CLOCK_MONOTONIC, &t0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	clock_gettime(CLOCK_MONOTONIC, &t1);
	/* (a wait longer than one 200 ms slice starts it: only where this
	 * machine was that slow is the count not checked) */
	if ((t1.tv_sec - t0.tv_sec) * 1000 + (t1.tv_nsec - t0.tv_nsec) / 1000000 < 200)
		CHECK(threads_of_self() == base);
	CHECK(cogw_subscribe(h, LINE, MBX_EVC_HB, NULL, 0, CALL_MS) == 0);
	CHECK(threads_of_self() == base + 1);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0); /* the helper and a caller share the queue */
	cogw_close(h);
	CHECK(threads_become(base));

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_send_async(h, LINE, MBX_CMD_OD_READ, &o, sizeof o, &corr) == 0);
	CHECK(threads_of_self() == base + 1);
	CHECK(cogw_recv(h, &m, CALL_MS) == 0);
	CHECK(m.kind == MBX_KIND_RESPONSE && m.corr == corr && m.status == 0);
	cogw_msg_release(&m);
	cogw_close(h);
	CHECK(threads_become(base));

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_event_fd(h) >= 0); /* an epoll loop's descriptor needs no thread */
	CHECK(threads_of_self() == base);
	CHECK(cogw_recv(h, &m, 0) == COGW_E_AGAIN);
	CHECK(threads_of_self() == base + 1);
	cogw_close(h);
	return 0;
}

static void test_helper_thread_starts_only_when_needed(void)
{
	mbx_server_config cfg = base_cfg();

	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_helper_on_need, NULL)));
	WAIT_FOR(stats().clients == 0, 5000);
	/* the third handle made no call: it never registered */
	TEST_ASSERT_EQUAL_UINT64(2, stats().clients_registered);
	TEST_ASSERT_EQUAL_UINT64(2, stats().clients_unregistered);
}

/* The depth the kernel gave the queue named like libcogw's response
 * queue of this process (/cogw.<instance>.c<pid>.*.resp), 0 if none, -1
 * when /dev/mqueue is not mounted here (the VM mounts it). */
static long resp_queue_depth_of_self(void)
{
	char prefix[64], name[300];
	DIR *d = opendir("/dev/mqueue");
	struct dirent *e;
	long depth = 0;

	if (!d)
		return -1;
	snprintf(prefix, sizeof prefix, "cogw.%s.c%d.", instance, (int)getpid());
	while ((e = readdir(d))) {
		size_t n = strlen(e->d_name);

		if (strncmp(e->d_name, prefix, strlen(prefix)) != 0 || n < 5 ||
		    strcmp(e->d_name + n - 5, ".resp") != 0)
			continue;
		snprintf(name, sizeof name, "/%s", e->d_name);
		mqd_t q = mq_open(name, O_RDONLY | O_NONBLOCK);
		struct mq_attr a;

		if (q != (mqd_t)-1 && mq_getattr(q, &a) == 0)
			depth = a.mq_maxmsg;
		if (q != (mqd_t)-1)
			mq_close(q);
	}
	closedir(d);
	return depth;
}

/* Without CAP_SYS_RESOURCE the kernel refuses a queue deeper than
 * fs.mqueue.msg_max: libcogw then clamps to it (read only in that case)
 * and the handle works. */
static int child_queues_deeper_than_msg_max(void *arg)
{
	unsigned long msg_max = 0;
	FILE *f = fopen("/proc/sys/fs/mqueue/msg_max", "re");
	cogw_options o = { .instance = instance };
	cogw *h;

	(void)arg;
	CHECK(f && fscanf(f, "%lu", &msg_max) == 1);
	fclose(f);
	CHECK(setgid(1000) == 0 && setuid(1000) == 0);
	o.resp_depth = o.event_depth = (unsigned)msg_max + 1;
	CHECK(cogw_open_opts(&h, &o) == 0);
	long depth = resp_queue_depth_of_self();

	CHECK(depth == (long)msg_max || depth < 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	cogw_close(h);
	return 0;
}

static void test_queues_clamped_to_msg_max_without_cap(void)
{
	mbx_access_rule rules[] = { { .uid = 1000, .access = MBX_ACCESS_READ } };
	mbx_server_config cfg = base_cfg();

	if (geteuid() != 0)
		TEST_IGNORE_MESSAGE("needs root (setuid to a test user)");
	cfg.rules = rules;
	cfg.n_rules = 1;
	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_queues_deeper_than_msg_max, NULL)));
	TEST_ASSERT_EQUAL_UINT64(1, stats().clients_registered);
}

/* ---- malformed commands, by hand --------------------------------------------------- */

typedef struct raw_client {
	char rname[MBX_QNAME_MAX], ename[MBX_QNAME_MAX];
	mqd_t cmd, resp, evt;
	uint32_t id;
	uint64_t token;
} raw_client;

static void raw_send(raw_client *rc, const mbx_hdr *h, const void *p, size_t len)
{
	uint8_t buf[1024];
	int n = mbx_msg_build(buf, sizeof buf, h, p, len);

	TEST_ASSERT_TRUE(n > 0);
	TEST_ASSERT_EQUAL_INT(0, mq_send(rc->cmd, (char *)buf, (size_t)n, 0));
}

static int raw_recv(raw_client *rc, mbx_hdr *h, void *p, size_t cap)
{
	uint8_t buf[1024];
	struct timespec ts;
	ssize_t n;

	clock_gettime(CLOCK_REALTIME, &ts);
	ts.tv_sec += 2;
	n = mq_timedreceive(rc->resp, (char *)buf, sizeof buf, NULL, &ts);
	if (n < 0)
		return -errno;
	TEST_ASSERT_EQUAL_INT(0, mbx_hdr_decode(buf, (size_t)n, h, NULL));
	if (p)
		memcpy(p, buf + MBX_HDR_SIZE, h->len < cap ? h->len : cap);
	return 0;
}

static mbx_hdr raw_hdr(raw_client *rc, uint16_t code, uint64_t corr)
{
	return (mbx_hdr){ .magic = MBX_MAGIC,
			  .version = MBX_VERSION,
			  .kind = MBX_KIND_COMMAND,
			  .code = code,
			  .line = LINE,
			  .client = rc->id,
			  .token = rc->token,
			  .corr = corr };
}

static void raw_open(raw_client *rc)
{
	struct mq_attr a = { .mq_maxmsg = 8, .mq_msgsize = 1024 };
	mbx_register_req r;
	mbx_register_resp rr;
	mbx_hdr h;

	snprintf(rc->rname, sizeof rc->rname, "/%s.raw.resp", instance);
	snprintf(rc->ename, sizeof rc->ename, "/%s.raw.evt", instance);
	mq_unlink(rc->rname);
	mq_unlink(rc->ename);
	rc->resp = mq_open(rc->rname, O_CREAT | O_EXCL | O_RDONLY, 0600, &a);
	rc->evt = mq_open(rc->ename, O_CREAT | O_EXCL | O_RDONLY, 0600, &a);
	rc->cmd = mq_open(qname, O_WRONLY | O_NONBLOCK);
	TEST_ASSERT_TRUE(rc->resp != (mqd_t)-1 && rc->evt != (mqd_t)-1 && rc->cmd != (mqd_t)-1);
	fchmod((int)rc->resp, 0600);
	fchmod((int)rc->evt, 0600);
	memset(&r, 0, sizeof r);
	r.pid = (uint32_t)getpid();
	r.uid = (uint32_t)geteuid();
	strcpy(r.resp_queue, rc->rname);
	strcpy(r.event_queue, rc->ename);
	rc->id = 0;
	rc->token = 0;
	h = raw_hdr(rc, MBX_CMD_REGISTER, 77);
	raw_send(rc, &h, &r, sizeof r);
	TEST_ASSERT_EQUAL_INT(0, raw_recv(rc, &h, &rr, sizeof rr));
	TEST_ASSERT_EQUAL_INT(0, h.status);
	TEST_ASSERT_EQUAL_UINT64(77, h.corr);
	TEST_ASSERT_EQUAL_UINT16(MBX_CMD_REGISTER, h.code);
	TEST_ASSERT_EQUAL_UINT16(sizeof rr, h.len);
	TEST_ASSERT_EQUAL_UINT32(rr.client, h.client);
	TEST_ASSERT_EQUAL_UINT8(MBX_ACCESS_WRITE, rr.access);
	TEST_ASSERT_EQUAL_UINT32(1024, rr.max_msg);
	TEST_ASSERT_NOT_EQUAL(0, rr.token);
	rc->id = rr.client;
	rc->token = rr.token;
}

static void raw_close(raw_client *rc)
{
	mq_close(rc->cmd);
	mq_close(rc->resp);
	mq_close(rc->evt);
	mq_unlink(rc->rname);
	mq_unlink(rc->ename);
}

/* send h (+ payload), expect an error answer with status and one more
 * count for reason */
static void expect_refused(raw_client *rc, mbx_hdr h, const void *p, size_t len, int status,
			   mbx_bad reason)
{
	uint64_t before = stats().malformed[reason];
	mbx_hdr r;

	raw_send(rc, &h, p, len);
	TEST_ASSERT_EQUAL_INT(0, raw_recv(rc, &r, NULL, 0));
	TEST_ASSERT_EQUAL_INT_MESSAGE(status, r.status, mbx_bad_to_string(reason));
	TEST_ASSERT_EQUAL_UINT64(h.corr, r.corr);
	TEST_ASSERT_EQUAL_UINT16(h.code, r.code);
	TEST_ASSERT_EQUAL_UINT8(MBX_KIND_RESPONSE, r.kind);
	WAIT_FOR(stats().malformed[reason] == before + 1, 500);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(before + 1, stats().malformed[reason],
					 mbx_bad_to_string(reason));
}

/* a refusal nobody can be told about: counted, nothing answered */
static void expect_silent(raw_client *rc, const uint8_t *buf, size_t n, mbx_bad reason)
{
	uint64_t before = stats().malformed[reason];
	struct mq_attr a;

	TEST_ASSERT_EQUAL_INT(0, mq_send(rc->cmd, (const char *)buf, n, 0));
	WAIT_FOR(stats().malformed[reason] == before + 1, 500);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(before + 1, stats().malformed[reason],
					 mbx_bad_to_string(reason));
	mq_getattr(rc->resp, &a);
	TEST_ASSERT_EQUAL_INT(0, a.mq_curmsgs);
}

static void test_malformed_commands_answered_and_counted(void)
{
	mbx_server_config cfg = base_cfg();
	raw_client rc;
	uint8_t buf[256] = { 0 };
	mbx_hdr h, r;
	mbx_nmt_req nmt = { .cs = 0x01 };
	int n;

	start(&cfg);
	raw_open(&rc);

	/* unidentifiable: short, bad magic, unknown client, wrong token */
	expect_silent(&rc, buf, 10, MBX_BAD_SHORT);
	h = raw_hdr(&rc, MBX_CMD_PING, 1);
	h.magic = 0xBEEF;
	n = mbx_msg_build(buf, sizeof buf, &h, NULL, 0);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_MAGIC);
	h = raw_hdr(&rc, MBX_CMD_PING, 1);
	h.token ^= 1;
	n = mbx_msg_build(buf, sizeof buf, &h, NULL, 0);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_CLIENT);
	h = raw_hdr(&rc, MBX_CMD_PING, 1);
	h.client += 1;
	n = mbx_msg_build(buf, sizeof buf, &h, NULL, 0);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_CLIENT);
	/* REGISTER with a queue name that is not one: nowhere to answer */
	mbx_register_req reg;

	memset(&reg, 0, sizeof reg);
	reg.pid = 1;
	strcpy(reg.resp_queue, "no-slash");
	strcpy(reg.event_queue, "/x");
	h = raw_hdr(&rc, MBX_CMD_REGISTER, 1);
	n = mbx_msg_build(buf, sizeof buf, &h, &reg, sizeof reg);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_QUEUE);
	strcpy(reg.resp_queue, "/does-not-exist-cogw");
	n = mbx_msg_build(buf, sizeof buf, &h, &reg, sizeof reg);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_QUEUE);

	/* identifiable: one per field, each answered with its status */
	h = raw_hdr(&rc, MBX_CMD_PING, 2);
	h.version = 9;
	expect_refused(&rc, h, NULL, 0, MBX_E_VERSION, MBX_BAD_VERSION);
	h = raw_hdr(&rc, MBX_CMD_PING, 3);
	h.kind = MBX_KIND_EVENT;
	h.token = 0; /* events carry none: then nobody is identified */
	n = mbx_msg_build(buf, sizeof buf, &h, NULL, 0);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_KIND);
	h = raw_hdr(&rc, MBX_CMD_PING, 3);
	h.kind = MBX_KIND_RESPONSE; /* with a token: decode says reserved */
	expect_refused(&rc, h, NULL, 0, MBX_E_MALFORMED, MBX_BAD_RESERVED);
	h = raw_hdr(&rc, MBX_CMD_PING, 4);
	h.line = LINE + 1;
	expect_refused(&rc, h, NULL, 0, MBX_E_BAD_LINE, MBX_BAD_LINE);
	h = raw_hdr(&rc, MBX_CMD_PING, 5);
	h.flags = 0x40;
	expect_refused(&rc, h, NULL, 0, MBX_E_MALFORMED, MBX_BAD_FLAGS);
	h = raw_hdr(&rc, MBX_CMD_PING, 6);
	h.status = -3;
	expect_refused(&rc, h, NULL, 0, MBX_E_MALFORMED, MBX_BAD_RESERVED);
	h = raw_hdr(&rc, MBX_CMD_PING, 7);
	h.chunk = 2;
	expect_refused(&rc, h, NULL, 0, MBX_E_MALFORMED, MBX_BAD_CHUNK);
	h = raw_hdr(&rc, 0x0A55, 8);
	expect_refused(&rc, h, NULL, 0, MBX_E_UNKNOWN_CMD, MBX_BAD_CMD);
	h = raw_hdr(&rc, MBX_CMD_NMT, 9);
	expect_refused(&rc, h, &nmt, 3, MBX_E_MALFORMED, MBX_BAD_SIZE);
	nmt.cs = 0x77;
	expect_refused(&rc, h, &nmt, sizeof nmt, MBX_E_PARAM, MBX_BAD_PARAM);
	/* len field lying about the payload */
	h = raw_hdr(&rc, MBX_CMD_PING, 10);
	n = mbx_msg_build(buf, sizeof buf, &h, NULL, 0);
	buf[42] = 8;
	{
		uint64_t before = stats().malformed[MBX_BAD_LEN];

		TEST_ASSERT_EQUAL_INT(0, mq_send(rc.cmd, (char *)buf, (size_t)n, 0));
		TEST_ASSERT_EQUAL_INT(0, raw_recv(&rc, &r, NULL, 0));
		TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, r.status);
		TEST_ASSERT_EQUAL_UINT64(10, r.corr);
		WAIT_FOR(stats().malformed[MBX_BAD_LEN] == before + 1, 500);
		TEST_ASSERT_EQUAL_UINT64(before + 1, stats().malformed[MBX_BAD_LEN]);
	}
	/* a continuation chunk that continues nothing */
	h = raw_hdr(&rc, MBX_CMD_OD_WRITE, 11);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE;
	h.chunk = 3;
	h.total = 100;
	expect_refused(&rc, h, buf, 10, MBX_E_SEQUENCE, MBX_BAD_SEQUENCE);
	/* NO_REPLY: counted, not answered */
	h = raw_hdr(&rc, 0x0A55, 12);
	h.flags = MBX_F_NO_REPLY;
	n = mbx_msg_build(buf, sizeof buf, &h, NULL, 0);
	expect_silent(&rc, buf, (size_t)n, MBX_BAD_CMD);

	/* and the server is fine: a PING is answered */
	h = raw_hdr(&rc, MBX_CMD_PING, 13);
	raw_send(&rc, &h, NULL, 0);
	TEST_ASSERT_EQUAL_INT(0, raw_recv(&rc, &r, NULL, 0));
	TEST_ASSERT_EQUAL_INT(0, r.status);
	TEST_ASSERT_EQUAL_UINT64(13, r.corr);
	TEST_ASSERT_EQUAL_UINT32(rc.id, r.client);
	TEST_ASSERT_EQUAL_UINT64(19, stats().malformed_total);
	TEST_ASSERT_EQUAL_UINT32(1, stats().clients);
	raw_close(&rc);
}

static void test_system_limit_check_names_the_sysctl(void)
{
	char err[256];
	unsigned long msg_max = 0;
	FILE *f = fopen("/proc/sys/fs/mqueue/msg_max", "r");
	char want[64];

	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_INT(1, fscanf(f, "%lu", &msg_max));
	fclose(f);
	TEST_ASSERT_EQUAL_INT(
		-ERANGE, mbx_check_system_limits((unsigned)msg_max + 1, 1024, err, sizeof err));
	snprintf(want, sizeof want, "fs.mqueue.msg_max is %lu", msg_max);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, want), err);
	TEST_ASSERT_EQUAL_INT(0, mbx_check_system_limits((unsigned)msg_max, 1024, err, sizeof err));
	printf("limits: %s\n", "ok");
}

/* cogw_open in a child whose RLIMIT_MSGQUEUE cannot hold one queue, or
 * whose descriptor table is full: the kernel says EMFILE for both, the
 * library tells them apart (the remedies differ). */
typedef struct open_limit_case {
	int resource; /* lowered to `limit` */
	rlim_t limit;
	bool fill_descriptor_table;
	int want_rc;
} open_limit_case;

static int child_open_under_limit(void *arg)
{
	const open_limit_case *c = arg;
	struct rlimit rl = { .rlim_cur = c->limit, .rlim_max = c->limit };
	cogw *h = NULL;

	if (setrlimit(c->resource, &rl) < 0)
		return 90;
	while (c->fill_descriptor_table && dup(1) >= 0)
		;
	int rc = cogw_open(&h, "limitq");
	if (rc == 0) {
		cogw_close(h);
		return 91;
	}
	return rc == c->want_rc && errno == EMFILE ? 0 : 92;
}

static void test_open_tells_queue_memory_from_descriptor_exhaustion(void)
{
	open_limit_case no_queue_memory = { RLIMIT_MSGQUEUE, 4096, false, COGW_E_QUEUE_LIMIT };
	open_limit_case no_descriptor = { RLIMIT_NOFILE, 64, true, COGW_E_SYSTEM };

	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_open_under_limit, &no_queue_memory)),
				      "RLIMIT_MSGQUEUE spent: want COGW_E_QUEUE_LIMIT");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_open_under_limit, &no_descriptor)),
				      "no descriptor left: want COGW_E_SYSTEM, errno EMFILE");
	TEST_ASSERT_NOT_NULL(strstr(cogw_strerror(COGW_E_QUEUE_LIMIT), "RLIMIT_MSGQUEUE"));
}

/* mbx_server_notify never truncates an event (an SDO_DONE used to be cut
 * to what fitted the client's event messages): one that does not fit is
 * refused, counted and flagged; one that fits arrives whole. */
static void test_notify_never_truncates(void)
{
	mbx_server_config cfg = base_cfg();
	static uint8_t big[1024];
	mbx_client_info ci;
	sync2 s;
	pid_t p;

	start(&cfg);
	sync_init(&s);
	p = spawn(child_park, &s);
	parent_wait_ready(&s);
	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_INT(0, mbx_server_client_info(fl.srv, 0, &ci));
	mbx_reply_to to = { .client = ci.id, .code = MBX_CMD_SDO_UPLOAD, .corr = 7 };
	/* the client's event messages are 1024 bytes, header included */
	size_t room = 1024 - MBX_HDR_SIZE;
	/* Results first, assertions after the unlock: a failed assertion
	 * must not leave the loop thread's mutex held. */
	int too_big_sdo = mbx_server_notify(fl.srv, &to, MBX_EV_SDO_DONE, big, room + 1);
	int too_big_emcy = mbx_server_notify(fl.srv, &to, MBX_EV_EMCY, big, room + 1);
	int info_rc = mbx_server_client_info(fl.srv, 0, &ci);
	mbx_ev_sdo_done done = { .size = 4, .index = 0x1000, .node = 5, .upload = 1 };
	int fits = mbx_server_notify(fl.srv, &to, MBX_EV_SDO_DONE, &done, sizeof done);
	pthread_mutex_unlock(&fl.mu);
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, too_big_sdo);
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, too_big_emcy);
	TEST_ASSERT_EQUAL_INT(0, info_rc);
	TEST_ASSERT_EQUAL_UINT64(2, ci.dropped);
	TEST_ASSERT_EQUAL_UINT32(2, ci.pending_drop_events);
	TEST_ASSERT_EQUAL_UINT64(2, stats().dropped);
	TEST_ASSERT_EQUAL_INT(0, fits);
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT(0, reap(p));
	sync_close(&s);
}

int main(void)
{
	pthread_mutex_init(&fl.mu, NULL);
	fl.rng = (uint64_t)getpid();
	signal(SIGPIPE, SIG_IGN);
	UNITY_BEGIN();
	RUN_TEST(test_register_call_and_correlation);
	RUN_TEST(test_chunked_transfers_both_ways);
	RUN_TEST(test_subscription_filtering_and_unsubscribe);
	RUN_TEST(test_three_clients_get_exactly_their_answers);
	RUN_TEST(test_full_client_queue_drops_counts_and_flags);
	RUN_TEST(test_notify_never_truncates);
	RUN_TEST(test_killed_client_is_reaped);
	RUN_TEST(test_client_with_unlinked_queue_is_reaped);
	RUN_TEST(test_lease_expiry);
	RUN_TEST(test_late_wake_renews_lapsed_leases_once);
	RUN_TEST(test_access_control_by_queue_owner);
	RUN_TEST(test_helper_thread_starts_only_when_needed);
	RUN_TEST(test_queues_clamped_to_msg_max_without_cap);
	RUN_TEST(test_malformed_commands_answered_and_counted);
	RUN_TEST(test_system_limit_check_names_the_sysctl);
	RUN_TEST(test_open_tells_queue_memory_from_descriptor_exhaustion);
	return UNITY_END();
}
