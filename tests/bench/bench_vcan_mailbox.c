/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the mailbox, end to end through a real cogwd on vcan0.
 *
 *   - round trip of a local object read (OD_READ 1018h:01 through libcogw)
 *     p50/p99, against a raw POSIX mq ping-pong between two processes with
 *     messages of the same sizes (target: <= 2x the raw ping-pong);
 *   - commands/s with 1, 4 and 16 client processes, against the raw
 *     ping-pong's round trips/s;
 *   - event fan-out: RPDO frames injected on vcan0, each one an MBX_EV_PDO
 *     event to 8 subscriber processes, against one process writing the same
 *     messages into 8 raw queues read by 8 processes. Both keep at most a
 *     window of messages in flight (the slowest reader paces the writer), so
 *     what is measured is sustained delivery, not queue overflow;
 *   - event fan-out latency to 1, 8 and 32 subscribers (one event in flight,
 *     frame sent to event read), against the fair baseline: a relay process
 *     that receives the same CAN frame on a CAN_RAW socket and then writes
 *     it into the raw queues, so that it pays what the daemon pays (a frame
 *     received, then the fan-out); the pure mq fan-out (no frame) in the
 *     notes. COGW_BENCH_MAILBOX_ONLY=fanout measures only the fan-out.
 *   - one-shot cogwctl: `cogwctl sdo read` of an expedited object of a
 *     simulated device (cosim on vcan0) from process start to exit, against
 *     this program started to make one raw mq round trip and one raw SDO
 *     request/answer with the same device (COGW_BENCH_MAILBOX_ONLY=oneshot:
 *     this figure alone).
 *
 * Needs vcan0 and build/rel/bin/cogwd: run through tests/bench/run-vcan
 * (make bench). Prints figures; asserts nothing, but says so loudly when a
 * value read back is wrong or events were lost.
 */
#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <math.h>
#include <net/if.h>
#include <poll.h>
#include <mqueue.h>
#include <sched.h>
#include <semaphore.h>
#include <signal.h>
#include <spawn.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define VENDOR_ID 0x0B16C0DEu
#define SUBSCRIBERS_MAX 32
/* subscribers of the fan-out pass under way (1, 8 or 32) */
static int subscribers = 8;
#define MAX_CLIENTS 16
#define RPDO_COB_ID 0x181u
#define SAMPLES_MAX 200000

static char instance[32];
static pid_t daemon_pid = -1;
/* the name of line bench0's thread in the daemon ("cogw-" + its name) */
#define LINE_THREAD "cogw-bench0"
static char tmpdir[128];
static double run_seconds = 2.0;

/* ---- raw POSIX mq ping-pong (baseline) --------------------------------------- */

/* The sizes the mailbox round trip uses: OD_READ = header + mbx_obj_req,
 * its answer = header + 4 value bytes, in queues of the mailbox's
 * mq_msgsize. */
#define PING_SIZE (MBX_HDR_SIZE + sizeof(mbx_obj_req))
#define PONG_SIZE (MBX_HDR_SIZE + 4u)
#define QUEUE_MSGSIZE 1024

static void queue_name(char *buf, size_t len, const char *what)
{
	snprintf(buf, len, "/cogw.%s.%s", instance, what);
}

static mqd_t queue_create(const char *name, unsigned depth, int flags)
{
	struct mq_attr a = { .mq_maxmsg = depth, .mq_msgsize = QUEUE_MSGSIZE };
	mq_unlink(name);
	return mq_open(name, O_CREAT | O_EXCL | flags | O_CLOEXEC, 0600, &a);
}

/* The raw baseline's other side: a child process answering every message
 * on ping with a PONG_SIZE message on pong, until a message starting 'q'. */
static pid_t raw_echo_start(mqd_t ping, mqd_t pong)
{
	pid_t child = fork();

	if (child == 0) {
		char buf[QUEUE_MSGSIZE] = { 0 };
		for (;;) {
			ssize_t n = mq_receive(ping, buf, sizeof buf, NULL);
			if (n <= 0 || buf[0] == 'q')
				_exit(0);
			buf[0] = 'p';
			mq_send(pong, buf, PONG_SIZE, 0);
		}
	}
	return child;
}

/* Returns the number of samples (RTTs in µs in rtt[]), or -1. */
static int raw_pingpong(double *rtt, size_t max, double seconds)
{
	char ping_name[64], pong_name[64];
	queue_name(ping_name, sizeof ping_name, "raw-ping");
	queue_name(pong_name, sizeof pong_name, "raw-pong");
	mqd_t ping = queue_create(ping_name, 8, O_RDWR), pong = queue_create(pong_name, 8, O_RDWR);
	if (ping == (mqd_t)-1 || pong == (mqd_t)-1) {
		printf("raw ping-pong: mq_open: %s\n", strerror(errno));
		return -1;
	}
	fflush(stdout);
	pid_t child = raw_echo_start(ping, pong);
	char msg[QUEUE_MSGSIZE] = { 0 }, in[QUEUE_MSGSIZE];
	size_t n = 0;
	double end = bench_now_s() + seconds;
	for (int warm = 0; warm < 200; warm++) {
		msg[0] = 'x';
		mq_send(ping, msg, PING_SIZE, 0);
		mq_receive(pong, in, sizeof in, NULL);
	}
	while (n < max && bench_now_s() < end) {
		uint64_t t0 = bench_now_ns();
		msg[0] = 'x';
		if (mq_send(ping, msg, PING_SIZE, 0) < 0 ||
		    mq_receive(pong, in, sizeof in, NULL) != (ssize_t)PONG_SIZE)
			break;
		rtt[n++] = (double)(bench_now_ns() - t0) * 1e-3;
	}
	msg[0] = 'q';
	mq_send(ping, msg, 1, 0);
	waitpid(child, NULL, 0);
	mq_close(ping);
	mq_close(pong);
	mq_unlink(ping_name);
	mq_unlink(pong_name);
	return (int)n;
}

/* ---- the daemon ---------------------------------------------------------------- */

static int write_config(const char *path, unsigned depth)
{
	char text[4096];
	snprintf(text, sizeof text,
		 "{\n"
		 " \"version\": 1,\n"
		 " \"state_dir\": \"%s/state\",\n"
		 " \"mailbox\": {\"instance\": \"%s\", \"depth\": %u, \"max_clients\": 48,\n"
		 "              \"max_clients_per_uid\": 48},\n"
		 " \"lines\": [{\n"
		 "  \"name\": \"bench0\", \"interface\": \"vcan0\", \"bitrate\": 1000000, "
		 "\"node_id\": 127,\n"
		 "  \"heartbeat_ms\": 1000, \"rpdos\": 1,\n"
		 "  \"device\": {\"name\": \"cogw bench\", \"vendor_id\": \"0x%08X\"},\n"
		 "  \"objects\": [{\"index\": \"0x2000\", \"object\": \"ARRAY\", \"type\": "
		 "\"UNSIGNED32\",\n"
		 "               \"length\": 2, \"access\": \"rww\", \"pdo\": true, \"default\": "
		 "0}],\n"
		 "  \"values\": [\n"
		 "   {\"index\": \"0x1400\", \"sub\": 1, \"value\": \"0x%03X\"},\n"
		 "   {\"index\": \"0x1600\", \"sub\": 0, \"value\": 2},\n"
		 "   {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0x20000120\"},\n"
		 "   {\"index\": \"0x1600\", \"sub\": 2, \"value\": \"0x20000220\"}]\n"
		 " },\n"
		 /* two more lines for commands/s spread over three lines */
		 " {\"name\": \"bench1\", \"interface\": \"vcan1\", \"bitrate\": 1000000, "
		 "\"node_id\": 127,\n"
		 "  \"device\": {\"name\": \"cogw bench\", \"vendor_id\": \"0x%08X\"}},\n"
		 " {\"name\": \"bench2\", \"interface\": \"vcan2\", \"bitrate\": 1000000, "
		 "\"node_id\": 127,\n"
		 "  \"device\": {\"name\": \"cogw bench\", \"vendor_id\": \"0x%08X\"}}]\n"
		 "}\n",
		 tmpdir, instance, depth, VENDOR_ID, RPDO_COB_ID, VENDOR_ID, VENDOR_ID);
	return bench_write_file(path, text);
}

/* deep_events: a subscriber's event queue as deep as allowed (up to 256);
 * otherwise libcogw's default. */
static cogw *client_open(bool deep_events)
{
	cogw *h = NULL;
	unsigned depth = bench_mq_msg_max();
	cogw_options o = { .instance = instance,
			   .timeout_ms = 10000,
			   .event_depth = deep_events ? (depth > 256 ? 256 : depth) : 0 };
	int rc = cogw_open_opts(&h, &o);
	if (rc < 0) {
		printf("cogw_open: %s\n", cogw_strerror(rc));
		return NULL;
	}
	return h;
}

/* One OD read of 1018h:01, checked. Returns 0, or the error. */
static int od_read_vendor_on(cogw *h, unsigned line)
{
	uint8_t v[4];
	size_t len = 0;
	uint32_t abort = 0;
	int rc = cogw_od_read(h, line, 0x1018, 1, v, sizeof v, &len, 10000, &abort);
	if (rc < 0)
		return rc;
	uint32_t got = (uint32_t)v[0] | (uint32_t)v[1] << 8 | (uint32_t)v[2] << 16 |
		       (uint32_t)v[3] << 24;
	return len == 4 && got == VENDOR_ID ? 0 : COGW_E_PROTOCOL;
}

static int od_read_vendor(cogw *h)
{
	return od_read_vendor_on(h, 0);
}

/* ---- mailbox round trip ----------------------------------------------------------- */

/* Round trips of read on h (200 warm-up ones first) for seconds, at most
 * max, into rtt (us); failures counted in *errors, the first named. */
static int rtt_measure(cogw *h, int (*read)(cogw *), const char *what, double *rtt, size_t max,
		       double seconds, int *errors)
{
	for (int warm = 0; warm < 200; warm++)
		if (read(h) < 0)
			(*errors)++;
	size_t n = 0;
	double end = bench_now_s() + seconds;
	while (n < max && bench_now_s() < end) {
		uint64_t t0 = bench_now_ns();
		int rc = read(h);
		double us = (double)(bench_now_ns() - t0) * 1e-3;
		if (rc < 0) {
			if ((*errors)++ < 3)
				printf("%s: OD read 1018:01: %s\n", what, cogw_strerror(rc));
			continue;
		}
		rtt[n++] = us;
	}
	return (int)n;
}

static int mailbox_rtt(double *rtt, size_t max, double seconds, int *errors)
{
	cogw *h = client_open(false);
	if (!h)
		return -1;
	*errors = 0;
	int n = rtt_measure(h, od_read_vendor, "mailbox round trip", rtt, max, seconds, errors);
	cogw_close(h);
	return n;
}

/* One OD read of 1018h:01 through a loop handle, as an event loop does it:
 * send, poll() the handle's descriptor, tick, take the answer. 0, or the
 * error. */
static uint64_t loop_polls, loop_polls_ready, loop_reads;

static int od_read_vendor_loop(cogw *h)
{
	mbx_obj_req rq = { .index = 0x1018, .sub = 1 };
	uint64_t corr = 0;
	int rc = cogw_loop_send(h, 0, MBX_CMD_OD_READ, &rq, sizeof rq, 10000, &corr);
	if (rc < 0)
		return rc;
	loop_reads++;
	for (;;) {
		struct pollfd pf = { .fd = cogw_loop_fd(h), .events = POLLIN };
		cogw_msg m;
		loop_polls++;
		loop_polls_ready += poll(&pf, 1, cogw_loop_timeout_ms(h)) > 0;
		cogw_loop_tick(h);
		while ((rc = cogw_loop_recv(h, &m)) == 0) {
			bool mine = m.kind == MBX_KIND_RESPONSE && m.corr == corr;
			int st = m.status;
			uint32_t got = 0;
			if (mine && st == 0 && m.len == 4)
				memcpy(&got, m.data, 4);
			cogw_msg_release(&m);
			if (mine)
				return st < 0 ? st : got == VENDOR_ID ? 0 : COGW_E_PROTOCOL;
		}
		if (rc != COGW_E_AGAIN)
			return rc;
	}
}

/* Round trips through the event-loop interface (cogw_loop_*), measured
 * like mailbox_rtt's blocking calls. */
static int loop_rtt(double *rtt, size_t max, double seconds, int *errors)
{
	cogw *h = NULL;
	int rc = cogw_loop_open(&h, &(cogw_options){ .instance = instance });
	if (rc == 0)
		rc = cogw_loop_attach(h, 0, 10000);
	if (rc < 0) {
		printf("event-loop round trip: %s\n", cogw_strerror(rc));
		cogw_close(h);
		return -1;
	}
	int n = rtt_measure(h, od_read_vendor_loop, "event-loop round trip", rtt, max, seconds,
			    errors);
	cogw_close(h);
	return n;
}

/* ---- commands/s with N client processes ------------------------------------------ */

struct client_result {
	uint64_t ok, errors;
};

/* clients processes, client i on line i % lines, for seconds: commands/s
 * of all together; *slowest_out: the rate of the slowest client (none may
 * starve). */
static double commands_per_s(int clients, unsigned lines, double seconds, uint64_t *errors_out,
			     double *slowest_out)
{
	int ready[2], go[2], results[2];
	if (pipe(ready) || pipe(go) || pipe(results))
		return -1;
	pid_t pids[MAX_CLIENTS];
	fflush(stdout);
	for (int i = 0; i < clients; i++) {
		pids[i] = fork();
		if (pids[i] == 0) {
			struct client_result r = { 0 };
			char c = 'r';
			close(ready[0]);
			close(results[0]);
			cogw *h = client_open(false);
			unsigned line = (unsigned)i % lines;
			/* the first command registers with the line: not timed */
			if (!h || od_read_vendor_on(h, line) < 0)
				c = 'e';
			fflush(stdout);
			if (write(ready[1], &c, 1) != 1 || read(go[0], &c, 1) != 1 || !h)
				_exit(2);
			double end = bench_now_s() + seconds;
			while (bench_now_s() < end) {
				if (od_read_vendor_on(h, line) == 0)
					r.ok++;
				else
					r.errors++;
			}
			cogw_close(h);
			fflush(stdout);
			if (write(results[1], &r, sizeof r) != (ssize_t)sizeof r)
				_exit(3);
			_exit(0);
		}
	}
	/* only the children write these: a child that dies ends in EOF, not
	 * in a parent waiting forever */
	close(ready[1]);
	close(results[1]);
	int up = 0;
	for (int i = 0; i < clients; i++) {
		char c;
		if (read(ready[0], &c, 1) == 1 && c == 'r')
			up++;
	}
	if (up != clients)
		printf("commands/s: only %d of %d clients registered\n", up, clients);
	double t0 = bench_now_s();
	char gos[MAX_CLIENTS];
	memset(gos, 'g', sizeof gos);
	if (write(go[1], gos, (size_t)clients) != clients)
		printf("commands/s: cannot start the clients\n");
	uint64_t ok = 0, errors = 0, slowest = UINT64_MAX;
	for (int i = 0; i < clients; i++) {
		struct client_result r;
		if (read(results[0], &r, sizeof r) == (ssize_t)sizeof r) {
			ok += r.ok;
			errors += r.errors;
			if (r.ok < slowest)
				slowest = r.ok;
		} else {
			slowest = 0;
		}
	}
	double elapsed = bench_now_s() - t0;
	*slowest_out = slowest == UINT64_MAX ? 0 : (double)slowest / seconds;
	for (int i = 0; i < clients; i++) {
		int st = 0;
		waitpid(pids[i], &st, 0);
		if (!WIFEXITED(st) || WEXITSTATUS(st) != 0)
			printf("commands/s: client %d of %d ended with status 0x%x\n", i + 1,
			       clients, (unsigned)st);
	}
	close(ready[0]);
	close(go[0]);
	close(go[1]);
	close(results[0]);
	*errors_out = errors;
	return (double)ok / elapsed;
}

/* ---- fan-out to 8 subscribers ------------------------------------------------------ */

struct fanout_shared {
	_Atomic uint64_t next_seq[SUBSCRIBERS_MAX]; /* highest sequence seen + 1 */
	_Atomic uint64_t received[SUBSCRIBERS_MAX];
	_Atomic uint64_t dropped[SUBSCRIBERS_MAX]; /* overflow reported */
	_Atomic int ready;
	double lat_p50[SUBSCRIBERS_MAX], lat_p99[SUBSCRIBERS_MAX];
	/* One event in flight (window 1): the writer sleeps until the last
	 * subscriber read it, woken by that subscriber; polling instead, its
	 * wake-ups would take the CPUs from the path being measured. */
	/* each subscriber's context switches (voluntary, involuntary) from
	 * ready to its last event */
	uint64_t switches[SUBSCRIBERS_MAX][2];
	_Atomic bool one_in_flight;
	_Atomic int unread; /* subscribers yet to read the event in flight */
	sem_t all_read;
};

/* Message of the raw baseline: the size of the MBX_EV_PDO the daemon sends
 * for our RPDO (header + mbx_ev_pdo + 2 values). */
#define FANOUT_MSG_SIZE (MBX_HDR_SIZE + sizeof(mbx_ev_pdo) + 2 * sizeof(mbx_pdo_value))

static uint64_t min_next_seq(struct fanout_shared *s)
{
	uint64_t m = UINT64_MAX;
	for (int i = 0; i < subscribers; i++) {
		uint64_t v = atomic_load(&s->next_seq[i]);
		if (v < m)
			m = v;
	}
	return m;
}

/* Subscriber idx read event seq. */
static void fanout_seen(struct fanout_shared *s, int idx, uint32_t seq)
{
	atomic_fetch_add(&s->received[idx], 1);
	atomic_store(&s->next_seq[idx], (uint64_t)seq + 1);
	if (atomic_load(&s->one_in_flight) && atomic_fetch_sub(&s->unread, 1) == 1)
		sem_post(&s->all_read);
}

/* This process's context switches: [0] voluntary, [1] involuntary,
 * since[] subtracted. */
static void switches_since(uint64_t out[2], const uint64_t since[2])
{
	struct rusage ru;
	getrusage(RUSAGE_SELF, &ru);
	out[0] = (uint64_t)ru.ru_nvcsw - since[0];
	out[1] = (uint64_t)ru.ru_nivcsw - since[1];
}

static void record_latencies(struct fanout_shared *s, int idx, double *lat, size_t n)
{
	uint64_t at_ready[2] = { s->switches[idx][0], s->switches[idx][1] };
	switches_since(s->switches[idx], at_ready);
	s->lat_p50[idx] = bench_percentile(lat, n, 50);
	s->lat_p99[idx] = bench_percentile(lat, n, 99);
}

static void daemon_subscriber(struct fanout_shared *s, int idx, uint64_t total)
{
	double *lat = malloc(sizeof(double) * total);
	size_t nlat = 0;
	cogw *h = client_open(true);
	if (!h || !lat || cogw_subscribe(h, 0, MBX_EVC_PDO, NULL, 0, 10000) < 0)
		_exit(1);
	switches_since(s->switches[idx], (const uint64_t[2]){ 0, 0 });
	atomic_fetch_add(&s->ready, 1);
	while (atomic_load(&s->next_seq[idx]) < total) {
		cogw_msg m;
		int rc = cogw_recv(h, &m, 5000);
		if (rc == COGW_E_AGAIN)
			break; /* nothing for 5 s: the rest was lost */
		if (rc < 0)
			break;
		if (m.dropped)
			atomic_fetch_add(&s->dropped[idx], m.dropped);
		if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_PDO &&
		    m.len >= sizeof(mbx_ev_pdo) + 2 * sizeof(mbx_pdo_value)) {
			mbx_pdo_value v[2];
			memcpy(v, m.data + sizeof(mbx_ev_pdo), sizeof v);
			uint32_t seq, sent_us;
			memcpy(&seq, v[0].data, 4);
			memcpy(&sent_us, v[1].data, 4);
			uint32_t now_us = (uint32_t)(bench_now_ns() / 1000u);
			if (nlat < total)
				lat[nlat++] = (double)(uint32_t)(now_us - sent_us);
			fanout_seen(s, idx, seq);
		}
		cogw_msg_release(&m);
	}
	record_latencies(s, idx, lat, nlat);
	cogw_close(h);
	_exit(0);
}

static void raw_subscriber(struct fanout_shared *s, int idx, uint64_t total)
{
	char name[64], what[16], buf[QUEUE_MSGSIZE];
	double *lat = malloc(sizeof(double) * total);
	size_t nlat = 0;
	snprintf(what, sizeof what, "raw-fan%d", idx);
	queue_name(name, sizeof name, what);
	mqd_t q = mq_open(name, O_RDONLY | O_CLOEXEC);
	if (q == (mqd_t)-1 || !lat)
		_exit(1);
	switches_since(s->switches[idx], (const uint64_t[2]){ 0, 0 });
	atomic_fetch_add(&s->ready, 1);
	while (atomic_load(&s->next_seq[idx]) < total) {
		struct timespec until;
		clock_gettime(CLOCK_REALTIME, &until);
		until.tv_sec += 5;
		ssize_t n = mq_timedreceive(q, buf, sizeof buf, NULL, &until);
		if (n < 0)
			break;
		uint32_t seq, sent_us;
		memcpy(&seq, buf + MBX_HDR_SIZE, 4);
		memcpy(&sent_us, buf + MBX_HDR_SIZE + 4, 4);
		lat[nlat++] = (double)(uint32_t)((uint32_t)(bench_now_ns() / 1000u) - sent_us);
		fanout_seen(s, idx, seq);
	}
	record_latencies(s, idx, lat, nlat);
	mq_close(q);
	_exit(0);
}

struct fanout_result {
	double events_per_s; /* delivered to all subscribers together */
	uint64_t delivered, expected, dropped;
	double lat_p50, lat_p99; /* median of the p50s, worst p99 */
	/* context switches per event: of a subscriber (mean), and of what
	 * fans out (the relay process, the daemon's line thread) */
	double sub_vol, sub_invol, fan_vol, fan_invol;
};

/* Writer side, shared by both variants: send(seq) puts message seq out. */
typedef int (*fanout_send_fn)(void *ctx, uint32_t seq);

static int fanout_run(struct fanout_shared *s, pid_t *pids, uint64_t total, unsigned window,
		      fanout_send_fn send, void *ctx, struct fanout_result *out)
{
	uint64_t wait_until = bench_now_ns() + 20000000000ull;
	while (atomic_load(&s->ready) < subscribers && bench_now_ns() < wait_until)
		sched_yield();
	if (atomic_load(&s->ready) < subscribers)
		printf("fan-out: only %d of %d subscribers came up\n", atomic_load(&s->ready),
		       subscribers);
	double t0 = bench_now_s();
	uint64_t last_progress = bench_now_ns(), last_min = 0;
	atomic_store(&s->one_in_flight, window == 1);
	for (uint64_t seq = 0; seq < total; seq++) {
		if (window == 1) {
			atomic_store(&s->unread, subscribers);
			if (send(ctx, (uint32_t)seq) < 0)
				goto failed;
			struct timespec until;
			clock_gettime(CLOCK_REALTIME, &until);
			until.tv_sec += 5;
			while (sem_timedwait(&s->all_read, &until) != 0)
				if (errno != EINTR)
					goto done;
			continue;
		}
		/* pace: at most `window` messages ahead of the slowest reader */
		for (;;) {
			uint64_t m = min_next_seq(s);
			if (m != last_min) {
				last_min = m;
				last_progress = bench_now_ns();
			}
			if (seq < m + window)
				break;
			if (bench_now_ns() - last_progress > 5000000000ull)
				goto done;
			struct timespec ts = { 0, 20000 };
			nanosleep(&ts, NULL);
		}
		if (send(ctx, (uint32_t)seq) < 0)
			goto failed;
	}
	goto done;
failed:
	printf("fan-out: a send failed: %s\n", strerror(errno));
done:
	for (int i = 0; i < subscribers; i++)
		waitpid(pids[i], NULL, 0);
	double elapsed = bench_now_s() - t0;
	memset(out, 0, sizeof *out);
	out->expected = total * subscribers;
	double p50s[SUBSCRIBERS_MAX];
	for (int i = 0; i < subscribers; i++) {
		out->delivered += atomic_load(&s->received[i]);
		out->dropped += atomic_load(&s->dropped[i]);
		p50s[i] = s->lat_p50[i];
		out->sub_vol += (double)s->switches[i][0] / (double)(total * subscribers);
		out->sub_invol += (double)s->switches[i][1] / (double)(total * subscribers);
		if (s->lat_p99[i] > out->lat_p99)
			out->lat_p99 = s->lat_p99[i];
	}
	out->lat_p50 = bench_percentile(p50s, subscribers, 50);
	out->events_per_s = (double)out->delivered / elapsed;
	return 0;
}

struct raw_fan_ctx {
	mqd_t q[SUBSCRIBERS_MAX];
};

static int raw_fan_send(void *ctx, uint32_t seq)
{
	struct raw_fan_ctx *c = ctx;
	char msg[FANOUT_MSG_SIZE] = { 0 };
	uint32_t now_us = (uint32_t)(bench_now_ns() / 1000u);
	memcpy(msg + MBX_HDR_SIZE, &seq, 4);
	memcpy(msg + MBX_HDR_SIZE + 4, &now_us, 4);
	/* like the daemon: non-blocking sends, one per subscriber */
	for (int i = 0; i < subscribers; i++)
		if (mq_send(c->q[i], msg, sizeof msg, 0) < 0 && errno != EAGAIN)
			return -1;
	return 0;
}

static int can_fan_send(void *ctx, uint32_t seq)
{
	int fd = *(int *)ctx;
	uint8_t data[8];
	uint32_t now_us = (uint32_t)(bench_now_ns() / 1000u);
	memcpy(data, &seq, 4);
	memcpy(data + 4, &now_us, 4);
	return can_send_std(fd, RPDO_COB_ID, data, 8);
}

static struct fanout_shared *shared_new(void)
{
	void *p = mmap(NULL, sizeof(struct fanout_shared), PROT_READ | PROT_WRITE,
		       MAP_SHARED | MAP_ANONYMOUS, -1, 0);
	if (p == MAP_FAILED)
		return NULL;
	memset(p, 0, sizeof(struct fanout_shared));
	if (sem_init(&((struct fanout_shared *)p)->all_read, 1, 0) != 0) {
		munmap(p, sizeof(struct fanout_shared));
		return NULL;
	}
	return p;
}

/* Context switches per event of process pid's threads named thread (NULL:
 * all), before[] subtracted, into out->fan_*. */
static void fan_switches(pid_t pid, const char *thread, const uint64_t before[2], uint64_t events,
			 struct fanout_result *out)
{
	uint64_t vol, invol;
	if (bench_ctx_switches(pid, thread, &vol, &invol) == 0 && events) {
		out->fan_vol = (double)(vol - before[0]) / (double)events;
		out->fan_invol = (double)(invol - before[1]) / (double)events;
	}
}

/* The fair baseline's relay (a child process): what the daemon's line
 * thread does for an RPDO, at the least it can cost - block on a CAN_RAW
 * socket, take the frame, encode one message (the frame's sequence number
 * and send time where raw_subscriber reads them), one non-blocking mq_send
 * per subscriber queue. Ends when killed. */
static void raw_relay(int can_fd, const struct raw_fan_ctx *c)
{
	char msg[FANOUT_MSG_SIZE] = { 0 };

	for (;;) {
		struct can_frame f;
		if (read(can_fd, &f, sizeof f) != (ssize_t)sizeof f)
			_exit(1);
		if (f.can_id != RPDO_COB_ID || f.len != 8)
			continue;
		memcpy(msg + MBX_HDR_SIZE, f.data, 8);
		for (int i = 0; i < subscribers; i++)
			if (mq_send(c->q[i], msg, sizeof msg, 0) < 0 && errno != EAGAIN)
				_exit(1);
	}
}

/* The relay's interface: a line the daemon does not serve (vcan3 under
 * `tests/vcan/run -n 4`), so that the daemon's line thread does not wake
 * for the baseline's frames; vcan0 where there is no vcan3. */
static const char *relay_interface(void)
{
	return access("/sys/class/net/vcan3", F_OK) == 0 ? "vcan3" : "vcan0";
}

/* A CAN_RAW socket on ifname that takes only the RPDO's identifier (the
 * daemon's socket is not filtered by identifier: its kernel work is no
 * less). */
static int can_open_rpdo_only(const char *ifname)
{
	int fd = can_open_raw(ifname);
	struct can_filter only = { .can_id = RPDO_COB_ID, .can_mask = CAN_SFF_MASK };
	if (fd >= 0 && setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &only, sizeof only) != 0) {
		close(fd);
		return -1;
	}
	return fd;
}

/* Raw fan-out to `subscribers` raw queues. relay_if NULL: this process
 * writes the messages into the queues itself (no CAN frame: the pure mq
 * floor); otherwise the fair baseline: each message is a CAN frame sent on
 * relay_if, received by raw_relay, which fans it out. */
static int fanout_raw(uint64_t total, unsigned window, unsigned depth, const char *relay_if,
		      struct fanout_result *out)
{
	struct fanout_shared *s = shared_new();
	struct raw_fan_ctx c;
	char names[SUBSCRIBERS_MAX][64];
	pid_t pids[SUBSCRIBERS_MAX], relay = -1;
	int relay_fd = -1, send_fd = -1;
	if (!s)
		return -1;
	for (int i = 0; i < subscribers; i++) {
		char what[16];
		snprintf(what, sizeof what, "raw-fan%d", i);
		queue_name(names[i], sizeof names[i], what);
		c.q[i] = queue_create(names[i], depth, O_WRONLY | O_NONBLOCK);
		if (c.q[i] == (mqd_t)-1) {
			printf("raw fan-out: mq_open: %s\n", strerror(errno));
			return -1;
		}
	}
	if (relay_if) {
		/* bound before the first frame is sent: no frame can miss it */
		relay_fd = can_open_rpdo_only(relay_if);
		send_fd = can_open_raw(relay_if);
		if (relay_fd < 0 || send_fd < 0) {
			printf("raw relay: cannot open %s\n", relay_if);
			return -1;
		}
	}
	fflush(stdout);
	for (int i = 0; i < subscribers; i++)
		if ((pids[i] = fork()) == 0)
			raw_subscriber(s, i, total);
	if (relay_if) {
		if ((relay = fork()) == 0)
			raw_relay(relay_fd, &c);
		close(relay_fd);
		fanout_run(s, pids, total, window, can_fan_send, &send_fd, out);
		fan_switches(relay, NULL, (const uint64_t[2]){ 0, 0 }, total, out);
		kill(relay, SIGKILL);
		waitpid(relay, NULL, 0);
		close(send_fd);
	} else {
		fanout_run(s, pids, total, window, raw_fan_send, &c, out);
	}
	for (int i = 0; i < subscribers; i++) {
		mq_close(c.q[i]);
		mq_unlink(names[i]);
	}
	munmap(s, sizeof *s);
	return 0;
}

static int fanout_daemon(uint64_t total, unsigned window, struct fanout_result *out)
{
	struct fanout_shared *s = shared_new();
	pid_t pids[SUBSCRIBERS_MAX];
	int fd = can_open_raw("vcan0");
	if (!s || fd < 0)
		return -1;
	fflush(stdout);
	for (int i = 0; i < subscribers; i++)
		if ((pids[i] = fork()) == 0)
			daemon_subscriber(s, i, total);
	uint64_t before[2] = { 0, 0 };
	bench_ctx_switches(daemon_pid, LINE_THREAD, &before[0], &before[1]);
	fanout_run(s, pids, total, window, can_fan_send, &fd, out);
	fan_switches(daemon_pid, LINE_THREAD, before, total, out);
	close(fd);
	munmap(s, sizeof *s);
	return 0;
}

/* RPDOs are only processed in OPERATIONAL: start the daemon's own node on
 * vcan0 with an NMT frame, as a manager of this network would, and check
 * that it got there. */
static int daemon_go_operational(void)
{
	int fd = can_open_raw("vcan0");
	cogw *h = client_open(false);
	int rc = -1;
	if (fd < 0 || !h)
		goto out;
	uint8_t start[2] = { 0x01, 127 };
	can_send_std(fd, 0x000, start, 2);
	for (uint64_t until = mono_ms() + 5000; mono_ms() < until; sleep_ms(20)) {
		mbx_line_status st;
		if (cogw_line_status(h, 0, &st, 5000) == 0 && st.nmt_state == 0x05) {
			rc = 0;
			break;
		}
	}
	if (rc < 0)
		printf("fan-out: the daemon's node did not become operational\n");
out:
	if (fd >= 0)
		close(fd);
	cogw_close(h);
	return rc;
}

/* ---- one-shot commands ---------------------------------------------------------- */

/* The device of the one-shot figure: cosim with the shipped pressure
 * transducer as node ONESHOT_NODE on vcan0, 1018h:01 (vendor-ID, an
 * expedited UNSIGNED32) the object both sides read. */
#define ONESHOT_NODE 5
#define ONESHOT_VENDOR 0x250u
#define ONESHOT_RUNS_MAX 100

/* The baseline's client: this program started again (--raw-once) to do the
 * least a one-shot command can do: a process start, one raw mq round trip
 * with the responder, one raw SDO expedited upload of 1018h:01 from the
 * same device on vcan0 (request, answer checked), exit. */
static int raw_once(const char *ping_name, const char *pong_name)
{
	mqd_t ping = mq_open(ping_name, O_WRONLY), pong = mq_open(pong_name, O_RDONLY);
	char msg[QUEUE_MSGSIZE] = { 'x' };
	if (ping == (mqd_t)-1 || pong == (mqd_t)-1)
		return 1;
	if (mq_send(ping, msg, PING_SIZE, 0) < 0 ||
	    mq_receive(pong, msg, sizeof msg, NULL) != (ssize_t)PONG_SIZE)
		return 1;
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
	struct ifreq ifr = { .ifr_name = "vcan0" };
	struct can_filter answer = { .can_id = 0x580 + ONESHOT_NODE,
				     .can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG };
	struct timeval patience = { 2, 0 };
	if (fd < 0 || ioctl(fd, SIOCGIFINDEX, &ifr) < 0 ||
	    setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &answer, sizeof answer) < 0 ||
	    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &patience, sizeof patience) < 0)
		return 1;
	struct sockaddr_can a = { .can_family = AF_CAN, .can_ifindex = ifr.ifr_ifindex };
	struct can_frame f = { .can_id = 0x600 + ONESHOT_NODE,
			       .len = 8,
			       .data = { 0x40, 0x18, 0x10, 0x01 } };
	if (bind(fd, (struct sockaddr *)&a, sizeof a) < 0 || write(fd, &f, sizeof f) != sizeof f ||
	    read(fd, &f, sizeof f) != sizeof f)
		return 1;
	/* expedited upload response, 4 bytes: 43h, index, sub, value */
	uint32_t value = f.data[4] | f.data[5] << 8 | f.data[6] << 16 | (uint32_t)f.data[7] << 24;
	return f.data[0] == 0x43 && f.data[1] == 0x18 && f.data[2] == 0x10 && f.data[3] == 0x01 &&
			       value == ONESHOT_VENDOR
		       ? 0
		       : 1;
}

/* Wall time of one run of argv (stdout/stderr to /dev/null) in µs, or -1
 * when it could not start or did not exit with status 0. */
static double run_us(char *const argv[])
{
	posix_spawn_file_actions_t fa;
	posix_spawn_file_actions_init(&fa);
	posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
	posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
	uint64_t t0 = bench_now_ns();
	pid_t pid;
	int st = -1;
	bool ok = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ) == 0 &&
		  waitpid(pid, &st, 0) == pid && WIFEXITED(st) && WEXITSTATUS(st) == 0;
	double us = (double)(bench_now_ns() - t0) * 1e-3;
	posix_spawn_file_actions_destroy(&fa);
	return ok ? us : -1;
}

/* cosim with the device of the one-shot figure; it answers SDO once it
 * runs: retry until it does. Returns its pid, or -1. */
static pid_t oneshot_device_start(const char *log)
{
	char prog[256];
	const char *argv[] = { bench_program("cosim", prog, sizeof prog),
			       "--interface",
			       "vcan0",
			       "--device",
			       "etc/devices/sti-pressure.json",
			       "--node-id",
			       "5",
			       "--quiet",
			       NULL };
	pid_t sim = proc_spawn(argv, log, NULL);
	cogw *h = client_open(false);
	for (uint64_t until = mono_ms() + 15000; sim > 0 && h && mono_ms() < until; sleep_ms(100)) {
		uint32_t v = 0, abort = 0;
		if (cogw_sdo_read_u32(h, 0, ONESHOT_NODE, 0x1018, 1, &v, 3000, &abort) == 0 &&
		    v == ONESHOT_VENDOR) {
			cogw_close(h);
			return sim;
		}
	}
	cogw_close(h);
	printf("one-shot: the simulated device does not answer SDO\n");
	proc_dump_log(log, 10);
	if (sim > 0)
		proc_stop(sim, SIGTERM, 5000);
	return -1;
}

/* p50 (p10 / p90) of n runs, as text. */
static void spread_text(char *buf, size_t len, double *v, int n)
{
	double p50 = bench_percentile(v, (size_t)n, 50);
	snprintf(buf, len, "p50 %.0f (p10 %.0f / p90 %.0f) us", p50,
		 bench_percentile(v, (size_t)n, 10), bench_percentile(v, (size_t)n, 90));
}

/* cogwctl sdo read of an expedited object of a real device on vcan0 (process
 * start to exit) against this program started to make one raw mq round
 * trip and one raw SDO request/answer with the same device, interleaved so
 * that host load falls on both alike. COGW_BENCH_CTL_BEFORE names another
 * cogwctl (e.g. main's) to interleave as well: before and after in one
 * boot, as a note. */
static void oneshot_figure(const char *tmp)
{
	char ping_name[64], pong_name[64], self[512], ctl[256], log[256];
	snprintf(log, sizeof log, "%s/cosim-oneshot.log", tmp);
	queue_name(ping_name, sizeof ping_name, "once-ping");
	queue_name(pong_name, sizeof pong_name, "once-pong");
	mqd_t ping = queue_create(ping_name, 8, O_RDWR), pong = queue_create(pong_name, 8, O_RDWR);
	ssize_t sl = readlink("/proc/self/exe", self, sizeof self - 1);
	if (ping == (mqd_t)-1 || pong == (mqd_t)-1 || sl <= 0) {
		printf("one-shot: cannot set up the baseline\n");
		return;
	}
	self[sl] = '\0';
	pid_t sim = oneshot_device_start(log);
	if (sim < 0)
		return;
	pid_t child = raw_echo_start(ping, pong);
	const char *before = getenv("COGW_BENCH_CTL_BEFORE");
	char *base_argv[] = { self, "--raw-once", ping_name, pong_name, NULL };
	char *ctl_argv[] = { (char *)bench_program("cogwctl", ctl, sizeof ctl),
			     "--instance",
			     instance,
			     "sdo",
			     "read",
			     "0",
			     "5",
			     "1018",
			     "1",
			     NULL };
	char *before_argv[sizeof ctl_argv / sizeof ctl_argv[0]];
	memcpy(before_argv, ctl_argv, sizeof ctl_argv);
	before_argv[0] = (char *)before;
	int runs = bench_in_vm() ? 40 : ONESHOT_RUNS_MAX, nb = 0, nc = 0, np = 0, failed = 0;
	double base[ONESHOT_RUNS_MAX], cmd[ONESHOT_RUNS_MAX], prev[ONESHOT_RUNS_MAX];
	for (int i = 0; i < runs; i++) {
		double b = run_us(base_argv), c = run_us(ctl_argv);
		double p = before && *before ? run_us(before_argv) : 0;
		if (b > 0)
			base[nb++] = b;
		if (c > 0)
			cmd[nc++] = c;
		if (p > 0)
			prev[np++] = p;
		failed += (b < 0) + (c < 0) + (p < 0);
	}
	char q[2] = "q";
	mq_send(ping, q, 1, 0);
	waitpid(child, NULL, 0);
	proc_stop(sim, SIGTERM, 5000);
	mq_close(ping);
	mq_close(pong);
	mq_unlink(ping_name);
	mq_unlink(pong_name);
	if (!nb || !nc) {
		printf("one-shot: no run succeeded (%d failed)\n", failed);
		return;
	}
	char ctl_spread[96], base_spread[96];
	spread_text(ctl_spread, sizeof ctl_spread, cmd, nc);
	spread_text(base_spread, sizeof base_spread, base, nb);
	double b50 = bench_percentile(base, (size_t)nb, 50),
	       c50 = bench_percentile(cmd, (size_t)nc, 50);
	bench_print_figure(&(bench_figure){
		.name = "one-shot cogwctl sdo read 0 5 1018 1 (expedited, cosim on vcan0), "
			"process start to exit, p50",
		.value = c50,
		.unit = "us",
		.base_name = "process start + raw mq round trip + raw SDO request/answer p50",
		.base_value = b50,
		.base_unit = "us",
		.ratio = c50 / b50,
		.target = "ratio <= 1.30",
		.verdict = bench_verdict(c50 <= 1.3 * b50) });
	bench_note("one-shot: %d runs each, interleaved; cogwctl %s, baseline %s; %d runs failed",
		   runs, ctl_spread, base_spread, failed);
	if (np) {
		char prev_spread[96];
		spread_text(prev_spread, sizeof prev_spread, prev, np);
		bench_note("one-shot: %s (interleaved with the above) %s, %.2fx the baseline",
			   before, prev_spread, bench_percentile(prev, (size_t)np, 50) / b50);
	}
}

static void print_rate(const char *name, double value, const char *bname, double base)
{
	bench_print_figure(&(bench_figure){ .name = name,
					    .value = value,
					    .unit = "1/s",
					    .base_name = bname,
					    .base_value = base,
					    .base_unit = "1/s",
					    .ratio = base > 0 ? value / base : -1,
					    .target = "none (context)",
					    .verdict = "-" });
}

/* The raw mq ping-pong before the daemon starts, while nothing else
 * runs: its mean round trip in *raw_mean. */
static int baseline(double *samples, double *raw_mean)
{
	int nraw = raw_pingpong(samples, SAMPLES_MAX, run_seconds);
	if (nraw <= 0)
		return -1;
	*raw_mean = 0;
	for (int i = 0; i < nraw; i++)
		*raw_mean += samples[i];
	*raw_mean /= nraw;
	return 0;
}

/* Round trips in ROUNDS rounds, each a raw ping-pong then the mailbox
 * (host load falls on both alike); the figures are the medians of the
 * rounds' percentiles, the note gives every round (the spread). */
static int round_trip_figures(double *samples, double raw_mean)
{
	enum {
		ROUNDS = 3
	};
	double m50[ROUNDS], m99[ROUNDS], r50[ROUNDS], r99[ROUNDS], l50[ROUNDS];
	int errors = 0, n = 0, loop_errors = 0;
	char spread[256] = "";
	for (int r = 0; r < ROUNDS; r++) {
		int nr = raw_pingpong(samples, SAMPLES_MAX, run_seconds / ROUNDS);
		if (nr <= 0)
			return -1;
		r50[r] = bench_percentile(samples, (size_t)nr, 50);
		r99[r] = bench_percentile(samples, (size_t)nr, 99);
		int nm = mailbox_rtt(samples, SAMPLES_MAX, run_seconds / ROUNDS, &errors);
		if (nm <= 0)
			return -1;
		n += nm;
		m50[r] = bench_percentile(samples, (size_t)nm, 50);
		m99[r] = bench_percentile(samples, (size_t)nm, 99);
		int nl = loop_rtt(samples, SAMPLES_MAX, run_seconds / ROUNDS, &loop_errors);
		if (nl <= 0)
			return -1;
		l50[r] = bench_percentile(samples, (size_t)nl, 50);
		size_t used = strlen(spread);
		snprintf(spread + used, sizeof spread - used, "%s%.0f/%.0f vs %.0f/%.0f",
			 r ? "; " : "", m50[r], m99[r], r50[r], r99[r]);
	}
	double p50 = bench_percentile(m50, ROUNDS, 50), p99 = bench_percentile(m99, ROUNDS, 50);
	double raw_p50 = bench_percentile(r50, ROUNDS, 50);
	double raw_p99 = bench_percentile(r99, ROUNDS, 50);
	bench_print_figure(&(bench_figure){ .name = "mailbox round trip p50 (OD read 1018h:01)",
					    .value = p50,
					    .unit = "us",
					    .base_name = "raw mq ping-pong p50",
					    .base_value = raw_p50,
					    .base_unit = "us",
					    .ratio = p50 / raw_p50,
					    .target = "ratio <= 1.50",
					    .verdict = bench_verdict(p50 <= 1.5 * raw_p50) });
	bench_print_figure(&(bench_figure){ .name = "mailbox round trip p99 (OD read 1018h:01)",
					    .value = p99,
					    .unit = "us",
					    .base_name = "raw mq ping-pong p99",
					    .base_value = raw_p99,
					    .base_unit = "us",
					    .ratio = p99 / raw_p99,
					    .target = "ratio <= 2.50",
					    .verdict = bench_verdict(p99 <= 2.5 * raw_p99) });
	double loop_p50 = bench_percentile(l50, ROUNDS, 50);
	bench_print_figure(&(bench_figure){
		.name = "event-loop round trip p50 (cogw_loop_*, OD read 1018h:01)",
		.value = loop_p50,
		.unit = "us",
		.base_name = "blocking call p50, same run",
		.base_value = p50,
		.base_unit = "us",
		.ratio = loop_p50 / p50,
		.target = "ratio <= 1.30",
		.verdict = bench_verdict(loop_p50 <= 1.3 * p50) });
	bench_note("event-loop round trips: %.2f poll() per read, %.2f of them found the "
		   "descriptor readable",
		   (double)loop_polls / (double)loop_reads,
		   (double)loop_polls_ready / (double)loop_polls);
	if (loop_errors)
		bench_note("event-loop round trips: %d failed or read a wrong value", loop_errors);
	bench_note("round trips: %d mailbox (%d failed or wrong value) in %d rounds, each round's "
		   "mailbox p50/p99 vs raw p50/p99 in us: %s; raw messages %zu/%zu bytes in "
		   "queues of %d; raw mean before the daemon started %.0f us",
		   n, errors, ROUNDS, spread, (size_t)PING_SIZE, (size_t)PONG_SIZE, QUEUE_MSGSIZE,
		   raw_mean);
	return 0;
}

/* Commands/s with 1, 4, 16 clients on one line and 4, 16 over three. */
static void command_rate_figures(double raw_rate)
{
	static const int counts[] = { 1, 4, 16 };
	double rates[3] = { 0 };
	for (unsigned lines = 1; lines <= 3; lines += 2) {
		for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++) {
			uint64_t errs = 0;
			double slowest = 0;
			if (lines == 3 && counts[i] == 1)
				continue; /* one client is on one line */
			double rate = commands_per_s(counts[i], lines, run_seconds, &errs,
						     &slowest);
			if (lines == 1)
				rates[i] = rate;
			char name[128];
			snprintf(name, sizeof name, "mailbox commands/s, %d client%s (OD read)%s",
				 counts[i], counts[i] == 1 ? "" : "s",
				 lines == 3 ? " spread over 3 lines" : "");
			print_rate(name, rate, "raw mq ping-pong round trips/s", raw_rate);
			if (counts[i] > 1)
				bench_note("%s: the slowest client made %.0f commands/s (an even "
					   "share: "
					   "%.0f)",
					   name, slowest, rate / counts[i]);
			if (errs)
				bench_note("%s: %llu commands failed or read a wrong value", name,
					   (unsigned long long)errs);
		}
	}
	bench_print_figure(
		&(bench_figure){ .name = "mailbox commands/s, 16 clients against 1 client",
				 .value = rates[2],
				 .unit = "1/s",
				 .base_name = "mailbox commands/s, 1 client",
				 .base_value = rates[0],
				 .base_unit = "1/s",
				 .ratio = rates[0] > 0 ? rates[2] / rates[0] : -1,
				 .target = "ratio >= 4.00",
				 .verdict = bench_verdict(rates[2] >= 4 * rates[0]) });
}

/* The latency passes of one subscriber count, in rounds: each round the
 * pure mq fan-out, the fair relay and the daemon one after the other, so
 * that host load falls on all three alike. */
enum {
	FANOUT_ROUNDS = 10
};

struct fanout_rounds {
	double mq[FANOUT_ROUNDS], relay[FANOUT_ROUNDS], daemon[FANOUT_ROUNDS]; /* p50s */
	double daemon_p99, relay_p99;                                          /* worst */
	uint64_t lost;
	/* context switches per event, voluntary + involuntary, summed over
	 * the rounds: of the line thread and the relay; of a subscriber */
	double line_sw[2], relay_sw[2], dsub_sw[2], rsub_sw[2];
};

static void add_switches(double sum[2], double vol, double invol)
{
	sum[0] += vol;
	sum[1] += invol;
}

static int fanout_latency_rounds(uint64_t per_pass, unsigned depth, struct fanout_rounds *fr)
{
	memset(fr, 0, sizeof *fr);
	for (int r = 0; r < FANOUT_ROUNDS; r++) {
		struct fanout_result mq, relay, dmn;
		if (fanout_raw(per_pass, 1, depth, NULL, &mq) < 0 ||
		    fanout_raw(per_pass, 1, depth, relay_interface(), &relay) < 0 ||
		    fanout_daemon(per_pass, 1, &dmn) < 0)
			return -1;
		fr->mq[r] = mq.lat_p50;
		fr->relay[r] = relay.lat_p50;
		fr->daemon[r] = dmn.lat_p50;
		fr->daemon_p99 = fmax(fr->daemon_p99, dmn.lat_p99);
		fr->relay_p99 = fmax(fr->relay_p99, relay.lat_p99);
		fr->lost += dmn.expected - dmn.delivered;
		add_switches(fr->line_sw, dmn.fan_vol, dmn.fan_invol);
		add_switches(fr->relay_sw, relay.fan_vol, relay.fan_invol);
		add_switches(fr->dsub_sw, dmn.sub_vol, dmn.sub_invol);
		add_switches(fr->rsub_sw, relay.sub_vol, relay.sub_invol);
	}
	return 0;
}

/* The target row (daemon against the fair relay: medians of the rounds'
 * p50s) and a note with every round (the spread) and the pure mq floor. */
static void fanout_latency_figure(struct fanout_rounds *fr, double max_ratio, uint64_t per_pass)
{
	char name[160], target[32] = "none (context)", spread[512] = "";
	double ratios[FANOUT_ROUNDS];
	for (int r = 0; r < FANOUT_ROUNDS; r++) {
		size_t used = strlen(spread);
		ratios[r] = fr->relay[r] > 0 ? fr->daemon[r] / fr->relay[r] : -1;
		snprintf(spread + used, sizeof spread - used, "%s%.0f/%.0f/%.0f", r ? "; " : "",
			 fr->daemon[r], fr->relay[r], fr->mq[r]);
	}
	double dmn = bench_percentile(fr->daemon, FANOUT_ROUNDS, 50);
	double relay = bench_percentile(fr->relay, FANOUT_ROUNDS, 50);
	double mq = bench_percentile(fr->mq, FANOUT_ROUNDS, 50);
	double ratio = relay > 0 ? dmn / relay : -1;
	snprintf(name, sizeof name,
		 "event fan-out latency p50 to %d subscriber%s, one event in flight (frame sent "
		 "to event read)",
		 subscribers, subscribers == 1 ? "" : "s");
	if (max_ratio > 0)
		snprintf(target, sizeof target, "ratio <= %.2f", max_ratio);
	bench_print_figure(&(bench_figure){
		.name = name,
		.value = dmn,
		.unit = "us",
		.base_name = "raw relay (CAN frame received, then mq fan-out) latency p50",
		.base_value = relay,
		.base_unit = "us",
		.ratio = ratio,
		.target = target,
		.verdict = max_ratio > 0 ? bench_verdict(ratio >= 0 && ratio <= max_ratio) : "-" });
	bench_note("fan-out latency to %d: %d rounds of %llu frames, each round's p50 daemon / "
		   "relay / pure mq in us: %s; daemon/relay per round %.2fx .. %.2fx; pure mq "
		   "fan-out (no CAN frame) p50 %.0f us; worst subscriber p99 daemon %.0f, relay "
		   "%.0f us%s",
		   subscribers, FANOUT_ROUNDS, (unsigned long long)per_pass, spread,
		   bench_percentile(ratios, FANOUT_ROUNDS, 0),
		   bench_percentile(ratios, FANOUT_ROUNDS, 100), mq, fr->daemon_p99, fr->relay_p99,
		   fr->lost ? "; EVENTS LOST" : "");
	const double n = FANOUT_ROUNDS;
	bench_note("fan-out to %d, context switches per event (voluntary + involuntary, mean of "
		   "the rounds): line thread %.2f + %.2f, relay %.2f + %.2f; each subscriber "
		   "of the daemon (libcogw, all its threads) %.2f + %.2f, of the relay %.2f + %.2f",
		   subscribers, fr->line_sw[0] / n, fr->line_sw[1] / n, fr->relay_sw[0] / n,
		   fr->relay_sw[1] / n, fr->dsub_sw[0] / n, fr->dsub_sw[1] / n, fr->rsub_sw[0] / n,
		   fr->rsub_sw[1] / n);
	if (fr->lost)
		printf("WARNING: the daemon lost %llu events to %d subscribers\n",
		       (unsigned long long)fr->lost, subscribers);
}

/* Event fan-out: throughput to 8 subscribers against the pure mq fan-out
 * (context), then latency to 1, 8 and 32 subscribers against the fair
 * relay (targets for 8 and 32). */
static int fanout_figures(unsigned msg_max)
{
	/* Fan-out: window = half the subscribers' event queue depth. */
	unsigned evdepth = msg_max > 256 ? 256 : msg_max;
	unsigned window = evdepth / 2 ? evdepth / 2 : 1;
	uint64_t total = bench_in_vm() ? 2000 : 20000;
	/* Latency with one message in flight (under a full window latency
	 * is only the window divided by the rate). */
	uint64_t lat_total = bench_in_vm() ? 100 : 1000;
	struct fanout_result raw, relay, dmn;
	subscribers = 8;
	if (daemon_go_operational() < 0 || fanout_raw(total, window, evdepth, NULL, &raw) < 0 ||
	    fanout_raw(total, window, evdepth, relay_interface(), &relay) < 0 ||
	    fanout_daemon(total, window, &dmn) < 0)
		return -1;
	print_rate("event fan-out to 8 subscribers (RPDO events delivered)", dmn.events_per_s,
		   "raw mq fan-out 1 writer to 8 readers", raw.events_per_s);
	bench_note("fan-out: %llu RPDO frames, window %u; daemon delivered %llu of %llu events "
		   "(overflow reported %llu), raw %llu of %llu; the raw relay (frames on %s) "
		   "delivered %.0f events/s (the daemon %.2fx that)",
		   (unsigned long long)total, window, (unsigned long long)dmn.delivered,
		   (unsigned long long)dmn.expected, (unsigned long long)dmn.dropped,
		   (unsigned long long)raw.delivered, (unsigned long long)raw.expected,
		   relay_interface(), relay.events_per_s,
		   relay.events_per_s > 0 ? dmn.events_per_s / relay.events_per_s : 0);
	if (dmn.delivered != dmn.expected)
		printf("WARNING: the daemon lost %llu events\n",
		       (unsigned long long)(dmn.expected - dmn.delivered));
	static const struct {
		int subscribers;
		double max_ratio; /* 0: context */
	} passes[] = { { 1, 0 }, { 8, 1.5 }, { 32, 2.0 } };
	for (size_t i = 0; i < sizeof passes / sizeof passes[0]; i++) {
		struct fanout_rounds fr;
		subscribers = passes[i].subscribers;
		if (fanout_latency_rounds(lat_total, evdepth, &fr) < 0)
			return -1;
		fanout_latency_figure(&fr, passes[i].max_ratio, lat_total);
	}
	subscribers = 8;
	bench_note("fan-out latency: the relay is one process blocked in read() on a CAN_RAW "
		   "socket on %s (a line the daemon does not serve), that sends the frame's "
		   "message to each raw queue with one non-blocking mq_send; the daemon's path is "
		   "the same frame on vcan0",
		   relay_interface());
	return 0;
}

int main(int argc, char **argv)
{
	if (argc == 4 && strcmp(argv[1], "--raw-once") == 0)
		return raw_once(argv[2], argv[3]);
	/* the responder of --raw-once, for tests/bench/oneshot-timeline: creates
	 * the two queues and answers until a message starting 'q' */
	if (argc == 4 && strcmp(argv[1], "--raw-echo") == 0) {
		mqd_t ping = queue_create(argv[2], 8, O_RDWR),
		      pong = queue_create(argv[3], 8, O_RDWR);
		if (ping == (mqd_t)-1 || pong == (mqd_t)-1) {
			printf("--raw-echo: mq_open: %s\n", strerror(errno));
			return 1;
		}
		pid_t child = raw_echo_start(ping, pong);
		int st = 1;
		waitpid(child, &st, 0);
		mq_unlink(argv[2]);
		mq_unlink(argv[3]);
		return child > 0 && WIFEXITED(st) ? WEXITSTATUS(st) : 1;
	}
	/* COGW_BENCH_MAILBOX_ONLY=oneshot: the daemon and the one-shot figure
	 * alone; =fanout: the fan-out figures alone; =rtt (below) */
	const char *only = getenv("COGW_BENCH_MAILBOX_ONLY");
	bool oneshot_only = only && strcmp(only, "oneshot") == 0;
	const char *secs = getenv("COGW_BENCH_SECONDS");
	if (secs && atof(secs) > 0)
		run_seconds = atof(secs);
	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "mbx") < 0) {
		printf("bench_vcan_mailbox: cannot create a temp directory\n");
		return 1;
	}
	char cfg[256], log[256], state[256];
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(state, sizeof state, "%s/state", tmpdir);
	unsigned msg_max = bench_mq_msg_max();
	unsigned depth = msg_max < 64 ? msg_max : 64;
	double *samples = malloc(sizeof(double) * SAMPLES_MAX);
	int status = 1;
	bench_daemon d = { .pid = -1 };

	uint64_t mq_limit = bench_raise_mq_limit();
	char limit[32] = "unlimited";
	if (mq_limit != UINT64_MAX)
		snprintf(limit, sizeof limit, "%llu bytes", (unsigned long long)mq_limit);
	printf("bench_vcan_mailbox: cogwd on vcan0, %.1f s per measurement, fs.mqueue.msg_max %u, "
	       "RLIMIT_MSGQUEUE %s\n",
	       run_seconds, msg_max, limit);

	bool fanout_only = only && strcmp(only, "fanout") == 0;
	/* =rtt: the round trips alone (blocking, event loop, raw) */
	bool rtt_only = only && strcmp(only, "rtt") == 0;
	double raw_mean = 0;
	if (oneshot_only) {
		if (write_config(cfg, depth) == 0 &&
		    bench_daemon_start(&d, cfg, instance, log) == 0) {
			oneshot_figure(tmpdir);
			status = 0;
		}
	} else if ((fanout_only || baseline(samples, &raw_mean) == 0) &&
		   write_config(cfg, depth) == 0 &&
		   bench_daemon_start(&d, cfg, instance, log) == 0 && (daemon_pid = d.pid) > 0 &&
		   (fanout_only || round_trip_figures(samples, raw_mean) == 0)) {
		if (!fanout_only && !rtt_only) {
			command_rate_figures(1e6 / raw_mean);
			oneshot_figure(tmpdir);
		}
		if (rtt_only || fanout_figures(msg_max) == 0)
			status = 0;
	}
	bench_daemon_stop(&d);
	bench_unlink_instance_queues(instance);
	snprintf(state, sizeof state, "%s/state", tmpdir);
	bench_tmpdir_remove(state);
	bench_tmpdir_remove(tmpdir);
	free(samples);
	return status;
}
