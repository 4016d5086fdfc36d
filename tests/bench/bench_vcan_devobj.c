/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: process data by device object (docs/devices.md) through a real
 * cogwd on vcan0.
 *
 * The line mirrors 32 slaves (nodes 1..32, `pdo: "auto"`), each described
 * by one EDS written here: 4 event-driven TPDOs (180h/280h/380h/480h + id),
 * each mapping four INTEGER16 sub-objects of 6401h. No device runs: the
 * benchmark itself sends the slaves' TPDOs on vcan0.
 *
 *   - latency: one TPDO frame in flight; the time from its send to the typed
 *     MBX_EV_DEV_VALUE of 6401h:01 in a client that watches it (libcogw),
 *     against a raw CAN reader process that gets the same frame in the same
 *     run (target: p50 <= 1.5x the raw reader);
 *   - load: 32 nodes x 4 TPDOs at 1 kHz each (128,000 frames/s offered) into
 *     the line; the line thread's CPU time against a bare reader process
 *     receiving the same frames (target <= 1.3x), while a client watches one
 *     object of each TPDO of node 1 (4,000 values/s) and counts the values
 *     it did not get (per-watch sequence gaps and overflow notices).
 *
 * Needs vcan0 and build/rel/bin/cogwd: run through tests/bench/run-vcan
 * (make bench). Prints figures; asserts nothing, but says so loudly when a
 * value is wrong or events were lost.
 */
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define NODES 32
#define TPDOS 4
#define RATE_PER_TPDO 1000.0
#define OUR_NODE 127
#define LATENCY_ROUNDS 400

static char instance[32];
static char tmpdir[128];

static int write_config(const char *path, const char *eds, unsigned depth)
{
	char t[16384];
	size_t n = 0;
	n += (size_t)snprintf(
		t + n, sizeof t - n,
		"{\"version\": 1, \"state_dir\": \"%s/state\",\n"
		" \"mailbox\": {\"instance\": \"%s\", \"depth\": %u},\n"
		" \"lines\": [{\"name\": \"dev0\", \"interface\": \"vcan0\", \"bitrate\": "
		"1000000,\n"
		"   \"node_id\": %d, \"rpdos\": %d, \"pdo\": \"auto\",\n   \"nodes\": [",
		tmpdir, instance, depth, OUR_NODE, NODES * TPDOS);
	for (int id = 1; id <= NODES; id++)
		n += (size_t)snprintf(t + n, sizeof t - n, "%s\n    {\"id\": %d, \"eds\": \"%s\"}",
				      id > 1 ? "," : "", id, eds);
	n += (size_t)snprintf(t + n, sizeof t - n, "]}]}\n");
	if (n >= sizeof t)
		return -ENOSPC;
	return bench_write_file(path, t);
}

static uint32_t tpdo_cob(int p, int id)
{
	return (uint32_t)(0x180 + 0x100 * p + id);
}

/* ---- processes sharing one page --------------------------------------------- */

struct shared {
	_Atomic int stop;
	_Atomic uint64_t reader_frames;
	_Atomic uint64_t sent, send_failed;
	_Atomic uint64_t raw_ns[LATENCY_ROUNDS]; /* latency: raw reader's reception */
};

/* Latency baseline: gets the TPDO of node 1 like the line does. */
static void raw_latency_reader(struct shared *s)
{
	int fd = can_open_raw("vcan0");
	if (fd < 0)
		_exit(1);
	struct can_filter f = { .can_id = tpdo_cob(0, 1), .can_mask = CAN_SFF_MASK };
	setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f);
	struct timeval tv = { 0, 200000 };
	setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
	while (!atomic_load(&s->stop)) {
		struct can_frame fr;
		if (read(fd, &fr, sizeof fr) != (ssize_t)sizeof fr)
			continue;
		uint64_t now = bench_now_ns();
		uint16_t k = (uint16_t)(fr.data[0] | fr.data[1] << 8);
		if (k < LATENCY_ROUNDS)
			atomic_store(&s->raw_ns[k], now);
	}
	_exit(0);
}

/* Load baseline: every frame of vcan0, batched like the line (recvmmsg). */
static void bare_reader(struct shared *s)
{
	int fd = can_open_raw("vcan0");
	if (fd < 0)
		_exit(1);
	struct timeval tv = { 0, 100000 };
	setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
	struct can_frame frames[32];
	struct iovec iov[32];
	struct mmsghdr msgs[32];
	memset(msgs, 0, sizeof msgs);
	for (int i = 0; i < 32; i++) {
		iov[i] = (struct iovec){ &frames[i], sizeof frames[i] };
		msgs[i].msg_hdr.msg_iov = &iov[i];
		msgs[i].msg_hdr.msg_iovlen = 1;
	}
	while (!atomic_load(&s->stop)) {
		int got = recvmmsg(fd, msgs, 32, MSG_WAITFORONE, NULL);
		if (got > 0)
			atomic_fetch_add_explicit(&s->reader_frames, (uint64_t)got,
						  memory_order_relaxed);
	}
	_exit(0);
}

/* Every TPDO of every slave at RATE_PER_TPDO, in 1 ms steps. The four
 * values of a frame count up, so a watcher can see every value change. */
static void injector(struct shared *s)
{
	int fd = can_open_raw("vcan0");
	if (fd < 0)
		_exit(1);
	enum {
		BATCH = NODES * TPDOS
	};
	static struct can_frame frames[BATCH];
	static struct iovec iov[BATCH];
	static struct mmsghdr msgs[BATCH];
	for (int i = 0; i < BATCH; i++) {
		frames[i].can_id = tpdo_cob(i % TPDOS, 1 + i / TPDOS);
		frames[i].can_dlc = 8;
		iov[i] = (struct iovec){ &frames[i], sizeof frames[i] };
		msgs[i].msg_hdr.msg_iov = &iov[i];
		msgs[i].msg_hdr.msg_iovlen = 1;
	}
	uint64_t k = 0;
	double t0 = bench_now_s();
	while (!atomic_load(&s->stop)) {
		uint64_t due = (uint64_t)((bench_now_s() - t0) * RATE_PER_TPDO);
		for (; k < due; k++) {
			for (int i = 0; i < BATCH; i++)
				for (int e = 0; e < 4; e++) {
					frames[i].data[2 * e] = (uint8_t)k;
					frames[i].data[2 * e + 1] = (uint8_t)(k >> 8);
				}
			int done = 0;
			while (done < BATCH) {
				int sent = sendmmsg(fd, msgs + done, (unsigned)(BATCH - done), 0);
				if (sent <= 0) {
					/* the interface's queue is full: what a saturated
					 * bus does too; the frame is not sent */
					atomic_fetch_add_explicit(&s->send_failed,
								  (uint64_t)(BATCH - done),
								  memory_order_relaxed);
					break;
				}
				done += sent;
			}
			atomic_fetch_add_explicit(&s->sent, (uint64_t)done, memory_order_relaxed);
		}
		struct timespec ts = { 0, 1000000 };
		nanosleep(&ts, NULL);
	}
	_exit(0);
}

/* ---- the client side ------------------------------------------------------------ */

static int watch(cogw *h, uint8_t node, uint8_t sub)
{
	mbx_dev_obj_req o = { .node = node, .index = 0x6401, .sub = sub };
	mbx_dev_watch_resp r;
	uint32_t abort = 0;
	int rc = cogw_dev_watch(h, 0, &o, 0, &r, 5000, &abort);
	if (rc < 0)
		printf("watch of node %u 6401h:%u failed: %d (abort %08X)\n", node, sub, rc, abort);
	return rc;
}

/* Wait for the next value event; the others (none are subscribed) are
 * released. Returns the value's fixed part, or -1 after timeout_ms. */
static int next_value(cogw *h, int timeout_ms, mbx_dev_value *v, int16_t *value, uint32_t *dropped)
{
	for (uint64_t until = mono_ms() + (uint64_t)timeout_ms; mono_ms() <= until;) {
		cogw_msg m;
		if (cogw_recv(h, &m, timeout_ms) < 0)
			return -1;
		if (dropped)
			*dropped += m.dropped;
		int rc = -1;
		const uint8_t *data;
		if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_DEV_VALUE &&
		    cogw_dev_value_parse(m.data, m.len, v, &data) == 0 && v->len == 2) {
			*value = (int16_t)(data[0] | data[1] << 8);
			rc = 0;
		}
		cogw_msg_release(&m);
		if (rc == 0)
			return 0;
	}
	return -1;
}

static int latency(cogw *h, struct shared *s)
{
	static double dmn[LATENCY_ROUNDS], raw[LATENCY_ROUNDS];
	int fd = can_open_raw("vcan0");
	if (fd < 0 || watch(h, 1, 1) < 0)
		return -1;
	size_t n = 0;
	int wrong = 0;
	for (uint16_t k = 0; k < LATENCY_ROUNDS; k++) {
		uint8_t d[8] = { (uint8_t)k, (uint8_t)(k >> 8), 0, 0, 0, 0, 0, 0 };
		uint64_t t0 = bench_now_ns();
		if (can_send_std(fd, tpdo_cob(0, 1), d, 8) < 0)
			break;
		mbx_dev_value v;
		int16_t value;
		if (next_value(h, 2000, &v, &value, NULL) < 0) {
			printf("latency: no value event for frame %u\n", k);
			break;
		}
		uint64_t t2 = bench_now_ns();
		wrong += value != (int16_t)k || v.node != 1 || v.index != 0x6401 || v.sub != 1 ||
			 v.type != MBX_T_INTEGER16;
		uint64_t traw = 0;
		for (uint64_t until = mono_ms() + 1000; !traw && mono_ms() < until;)
			if (!(traw = atomic_load(&s->raw_ns[k])))
				sleep_ms(1);
		if (!traw)
			continue;
		dmn[n] = (double)(t2 - t0) / 1000.0;
		raw[n] = (double)(traw - t0) / 1000.0;
		n++;
		sleep_ms(2);
	}
	close(fd);
	mbx_dev_obj_req o = { .node = 1, .index = 0x6401, .sub = 1 };
	cogw_dev_unwatch(h, 0, &o, 5000);
	if (wrong)
		printf("latency: %d values WRONG (value, object or type)\n", wrong);
	if (n < LATENCY_ROUNDS / 2) {
		printf("latency: only %zu of %d frames measured\n", n, LATENCY_ROUNDS);
		return -1;
	}
	double d50 = bench_percentile(dmn, n, 50), d99 = bench_percentile(dmn, n, 99);
	double r50 = bench_percentile(raw, n, 50), r99 = bench_percentile(raw, n, 99);
	bench_print_figure(&(bench_figure){
		.name = "TPDO frame on vcan0 -> typed value event (6401h:01 INTEGER16) in a "
			"watching client, p50",
		.value = d50,
		.unit = "us",
		.base_name = "the same frame -> a raw CAN reader process, p50",
		.base_value = r50,
		.base_unit = "us",
		.ratio = r50 > 0 ? d50 / r50 : -1,
		.target = "ratio <= 1.50",
		.verdict = bench_verdict(r50 > 0 && d50 / r50 <= 1.5) });
	bench_print_figure(&(bench_figure){ .name = "the same, p99",
					    .value = d99,
					    .unit = "us",
					    .base_name = "raw CAN reader p99",
					    .base_value = r99,
					    .base_unit = "us",
					    .ratio = r99 > 0 ? d99 / r99 : -1,
					    .target = "none (context)",
					    .verdict = "-" });
	bench_note("latency: %zu frames, one in flight; values checked: %s", n,
		   wrong ? "SOME WRONG" : "all right");
	return wrong ? -1 : 0;
}

static int load(cogw *h, pid_t daemon, struct shared *s, double window_s)
{
	pid_t tid = bench_find_thread(daemon, "cogw-dev0");
	if (tid < 0) {
		printf("no thread cogw-dev0 in cogwd\n");
		return -1;
	}
	for (uint8_t p = 0; p < TPDOS; p++)
		if (watch(h, 1, (uint8_t)(4 * p + 1)) < 0)
			return -1;
	pid_t rd = fork();
	if (rd == 0)
		bare_reader(s);
	pid_t inj = fork();
	if (inj == 0)
		injector(s);

	/* warm-up, draining what comes */
	uint32_t last_seq[TPDOS] = { 0 }, dropped = 0;
	uint64_t got = 0, gaps = 0;
	int16_t last_value[TPDOS] = { 0 };
	bool seen[TPDOS] = { false };
	uint64_t values_wrong = 0;
	double t_warm = bench_now_s() + 1.0;
	mbx_line_status st0, st1;
	double cpu0 = 0, rcpu0 = 0, t0 = 0;
	uint64_t rf0 = 0, sent0 = 0;
	bool measuring = false;
	for (;;) {
		double now = bench_now_s();
		if (!measuring && now >= t_warm) {
			if (cogw_line_status(h, 0, &st0, 5000) < 0)
				break;
			cpu0 = bench_thread_cpu_s(daemon, tid);
			rcpu0 = bench_thread_cpu_s(rd, rd);
			rf0 = atomic_load(&s->reader_frames);
			sent0 = atomic_load(&s->sent);
			t0 = bench_now_s();
			measuring = true;
			got = gaps = dropped = 0;
		}
		if (measuring && now >= t0 + window_s)
			break;
		mbx_dev_value v;
		int16_t value;
		if (next_value(h, 100, &v, &value, &dropped) < 0)
			continue;
		unsigned p = (unsigned)(v.sub - 1) / 4;
		if (p >= TPDOS || v.node != 1)
			continue;
		got++;
		if (seen[p]) {
			gaps += v.seq - last_seq[p] - 1;
			values_wrong += value == last_value[p];
		}
		seen[p] = true;
		last_seq[p] = v.seq;
		last_value[p] = value;
	}
	double t1 = bench_now_s();
	double cpu1 = bench_thread_cpu_s(daemon, tid), rcpu1 = bench_thread_cpu_s(rd, rd);
	uint64_t rf1 = atomic_load(&s->reader_frames), sent1 = atomic_load(&s->sent);
	int rc = cogw_line_status(h, 0, &st1, 5000);
	atomic_store(&s->stop, 1);
	waitpid(inj, NULL, 0);
	waitpid(rd, NULL, 0);
	if (rc < 0 || !measuring)
		return -1;

	double wall = t1 - t0;
	double line_pct = (cpu1 - cpu0) / wall * 100.0, reader_pct = (rcpu1 - rcpu0) / wall * 100.0;
	double offered = (double)(sent1 - sent0) / wall;
	double line_rate = (double)(st1.rx_frames - st0.rx_frames) / wall;
	double reader_rate = (double)(rf1 - rf0) / wall;
	char name[200];
	snprintf(name, sizeof name,
		 "CPU of the line thread, %d nodes x %d TPDOs mirrored, %.0f frames/s received "
		 "(%.0f offered)",
		 NODES, TPDOS, line_rate, offered);
	/* per frame, so that a line that received fewer frames than the reader
	 * is not flattered */
	double per_line = line_rate > 0 ? line_pct / line_rate : -1;
	double per_reader = reader_rate > 0 ? reader_pct / reader_rate : -1;
	bench_print_figure(&(bench_figure){
		.name = name,
		.value = line_pct,
		.unit = "% of a core",
		.base_name = "a bare reader process receiving the same frames",
		.base_value = reader_pct,
		.base_unit = "% of a core",
		.ratio = per_reader > 0 ? per_line / per_reader : -1,
		.target = "ratio (CPU per frame) <= 1.30",
		.verdict = bench_verdict(per_reader > 0 && per_line / per_reader <= 1.3) });
	bench_print_figure(&(bench_figure){ .name = "typed values a client watching 4 objects got",
					    .value = (double)got / wall,
					    .unit = "values/s",
					    .base_name = "values lost (sequence gaps + overflow)",
					    .base_value = (double)(gaps + dropped),
					    .base_unit = "values",
					    .ratio = -1,
					    .target = "no value lost",
					    .verdict = bench_verdict(gaps + dropped == 0) });
	bench_note("load: %.1f s window; the line received %.0f frames/s (%llu dropped by its "
		   "socket), the reader %.0f; injector send failures %llu; values that did not "
		   "change: %llu. Where fewer than 128,000 frames/s were offered, the VM's CPUs "
		   "(shared by injector, reader, line and client) were the limit",
		   wall, line_rate, (unsigned long long)(st1.rx_dropped - st0.rx_dropped),
		   reader_rate, (unsigned long long)atomic_load(&s->send_failed),
		   (unsigned long long)values_wrong);
	return 0;
}

int main(void)
{
	double window_s = 4.0;
	const char *secs = getenv("COGW_BENCH_SECONDS");
	if (secs && atof(secs) > 0)
		window_s = 2.0 * atof(secs);
	bench_raise_mq_limit();
	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "devobj") < 0)
		return 1;
	char cfg[256], log[256], eds[256];
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(eds, sizeof eds, "%s/slave.eds", tmpdir);
	unsigned msg_max = bench_mq_msg_max();
	bench_daemon d = { .pid = -1 };
	cogw *h = NULL;
	pid_t lr = -1;
	int status = 1;
	struct shared *s = mmap(NULL, sizeof *s, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS,
				-1, 0);
	if (s == MAP_FAILED)
		return 1;
	memset(s, 0, sizeof *s);

	printf("bench_vcan_devobj: cogwd mirroring %d slaves x %d TPDOs on vcan0\n", NODES, TPDOS);
	/* a deep event queue: the load's client keeps up on average, but the
	 * injector, the reader and the line share the VM's CPUs with it */
	cogw_options o = { .instance = instance,
			   .timeout_ms = 10000,
			   .event_depth = msg_max > 256 ? 256 : msg_max };
	if (bench_write_tpdo_eds(eds, TPDOS) < 0 ||
	    write_config(cfg, eds, msg_max < 64 ? msg_max : 64) < 0 ||
	    bench_daemon_start(&d, cfg, instance, log) < 0)
		goto out;
	if (cogw_open_opts(&h, &o) < 0 || bench_go_operational(h, OUR_NODE) < 0)
		goto out;
	fflush(stdout);
	if ((lr = fork()) == 0)
		raw_latency_reader(s);
	sleep_ms(200);
	int lat = latency(h, s);
	atomic_store(&s->stop, 1);
	waitpid(lr, NULL, 0);
	lr = -1;
	atomic_store(&s->stop, 0);
	fflush(stdout);
	if (load(h, d.pid, s, window_s) < 0 || lat < 0)
		goto out;
	status = 0;
out:
	atomic_store(&s->stop, 1);
	if (lr > 0)
		waitpid(lr, NULL, 0);
	cogw_close(h);
	if (status)
		printf("bench_vcan_devobj: FAILED, daemon log %s\n", log);
	bench_daemon_stop(&d);
	if (!status)
		bench_tmpdir_remove(tmpdir);
	return status;
}
