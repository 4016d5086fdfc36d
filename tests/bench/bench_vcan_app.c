/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: objects a client owns (docs/application.md), through a real
 * cogwd on vcan0.
 *
 *   - an SDO read (expedited) from the bus of a served object, whose value
 *     the owner gives at each read (the line hands the read to the owner as
 *     an event, the owner answers with APP_ANSWER, the line answers the
 *     frame), against the same read of a daemon-held object in the same run
 *     (answered by the line from its OD): p50 and p99. Target: p50 <= 2.5x
 *     (one more wake-up: the owner's).
 *
 * The reads alternate (held, served, held, ...) so that the load of the
 * machine falls on both alike. The SDO client is the core's own on a raw
 * socket (tests/integration/support/sdo_req.h); the owner is a libcogw
 * handle answering on a thread of this process.
 *
 * Needs vcan0 and build/rel/bin/cogwd: run through tests/bench/run-vcan
 * (make bench). Prints figures; asserts nothing, but says so loudly when a
 * value read back is wrong.
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sdo.h"
#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"
#include "tests/integration/support/sdo_req.h"

#define OWN_NODE 127
#define TOOL_NODE 5
#define SERVED 0x2100
#define HELD 0x2101
#define SERVED_VALUE 0x5E4FEDu
#define HELD_VALUE 0x4E1Du
#define SAMPLES_MAX 20000

static char instance[32], tmpdir[64];
static double run_seconds = 3.0;

static struct owner {
	cogw *h;
	pthread_t t;
	atomic_bool stop;
	atomic_ulong answered;
	bool running;
} own;

static int write_config(const char *path)
{
	char text[1536];
	unsigned uid = (unsigned)getuid();

	snprintf(text, sizeof text,
		 "{\"version\": 1, \"state_dir\": \"%s/state\","
		 " \"mailbox\": {\"instance\": \"%s\"},"
		 " \"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": %d,"
		 "  \"heartbeat_ms\": 0,"
		 "  \"objects\": [{\"index\": \"0x2100\", \"type\": \"UNSIGNED32\", \"access\": "
		 "\"rw\"},"
		 "   {\"index\": \"0x2101\", \"type\": \"UNSIGNED32\", \"access\": \"rw\", "
		 "\"default\": %u}],"
		 "  \"app\": {\"objects\": ["
		 "   {\"index\": \"0x2100\", \"kind\": \"served\", \"uid\": %u},"
		 "   {\"index\": \"0x2101\", \"kind\": \"held\", \"uid\": %u}]}}]}",
		 tmpdir, instance, OWN_NODE, HELD_VALUE, uid, uid);
	return bench_write_file(path, text);
}

/* The owner: every read of the served object answered at once. */
static void *owner_run(void *arg)
{
	(void)arg;
	const uint32_t v = SERVED_VALUE;
	while (!atomic_load(&own.stop)) {
		cogw_msg m;
		mbx_ev_app_ind ind;
		const uint8_t *data;
		if (cogw_recv(own.h, &m, 100) < 0)
			continue;
		if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_APP_IND &&
		    cogw_app_ind_parse(m.data, m.len, &ind, &data) == 0) {
			cogw_app_answer(own.h, 0, ind.ind, 0, &v, 4, 0);
			atomic_fetch_add(&own.answered, 1);
		}
		cogw_msg_release(&m);
	}
	return NULL;
}

/* One expedited read from the bus: its time in µs, or -1 (wrong value,
 * abort, no answer). */
static double timed_read(sdo_req *q, uint16_t index, uint32_t want)
{
	uint32_t v = 0;
	sdo_client_req r = { .upload = true,
			     .node_id = OWN_NODE,
			     .index = index,
			     .mode = SDO_MODE_EXPEDITED,
			     .buf = (uint8_t *)&v,
			     .cap = sizeof v };
	uint64_t t0 = bench_now_ns();
	if (sdo_req_submit(q, &r) < 0)
		return -1;
	/* the pool starts the transfer at its next tick: now, not after a
	 * wait for a frame that cannot come before the request went out */
	co_node_tick(q->node, sdo_req_now_us());
	while (!q->done && bench_now_ns() - t0 < 5000000000ull)
		sdo_req_step(q, 5);
	if (!q->done || q->res.abort || v != want)
		return -1;
	return (double)(bench_now_ns() - t0) / 1000.0;
}

static int measure(sdo_req *q, double *held, double *served, size_t *n)
{
	double until = bench_now_s() + run_seconds;
	*n = 0;
	/* warm-up: the first reads pay page faults on both sides */
	for (int i = 0; i < 20; i++)
		if (timed_read(q, HELD, HELD_VALUE) < 0 || timed_read(q, SERVED, SERVED_VALUE) < 0)
			return -1;
	while (bench_now_s() < until && *n < SAMPLES_MAX) {
		held[*n] = timed_read(q, HELD, HELD_VALUE);
		served[*n] = timed_read(q, SERVED, SERVED_VALUE);
		if (held[*n] < 0 || served[*n] < 0) {
			printf("bench_vcan_app: a read came back wrong (abort %08X)\n",
			       q->res.abort);
			return -1;
		}
		(*n)++;
	}
	return 0;
}

static void figures(double *held, double *served, size_t n)
{
	double h50 = bench_percentile(held, n, 50), h99 = bench_percentile(held, n, 99);
	double s50 = bench_percentile(served, n, 50), s99 = bench_percentile(served, n, 99);
	double ratio = s50 / h50;
	bench_figure f = { .name = "SDO read of a served object from the bus p50",
			   .value = s50,
			   .unit = "us",
			   .base_name = "the same read of a daemon-held object p50",
			   .base_value = h50,
			   .base_unit = "us",
			   .ratio = ratio,
			   .target = "ratio <= 2.50",
			   .verdict = bench_verdict(ratio <= 2.5) };
	bench_print_figure(&f);
	f = (bench_figure){ .name = "SDO read of a served object from the bus p99",
			    .value = s99,
			    .unit = "us",
			    .base_name = "the same read of a daemon-held object p99",
			    .base_value = h99,
			    .base_unit = "us",
			    .ratio = s99 / h99,
			    .target = "none (context)",
			    .verdict = "-" };
	bench_print_figure(&f);
	bench_note("served vs held reads: %zu of each, alternating; the owner answered %lu "
		   "indications",
		   n, atomic_load(&own.answered));
}

int main(void)
{
	const char *secs = getenv("COGW_BENCH_SECONDS");
	char cfg[256], log[256];
	bench_daemon d = { .pid = -1 };
	static double held[SAMPLES_MAX], served[SAMPLES_MAX];
	sdo_req q = { 0 };
	int status = 1, fd = -1;
	size_t n = 0;

	if (secs && atof(secs) > 0)
		run_seconds = atof(secs);
	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "app") < 0)
		return 1;
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	printf("bench_vcan_app: cogwd on vcan0, a served and a held object, %.1f s\n", run_seconds);
	if (write_config(cfg) < 0 || bench_daemon_start(&d, cfg, instance, log) < 0)
		goto out;
	static const mbx_app_claim_req claims[2] = { { .index = SERVED, .kind = MBX_APP_SERVED },
						     { .index = HELD, .kind = MBX_APP_HELD } };
	if (cogw_open(&own.h, instance) < 0 || cogw_app_claim(own.h, 0, &claims[0], NULL, 0, 0) ||
	    cogw_app_claim(own.h, 0, &claims[1], NULL, 0, 0) ||
	    pthread_create(&own.t, NULL, owner_run, NULL)) {
		printf("bench_vcan_app: the owner could not claim its objects\n");
		goto out;
	}
	own.running = true;
	fd = can_open_raw("vcan0");
	if (fd < 0 || sdo_req_init(&q, fd, TOOL_NODE, 2000) < 0)
		goto out;
	if (measure(&q, held, served, &n) == 0 && n > 0) {
		figures(held, served, n);
		status = 0;
	}
out:
	if (own.running) {
		atomic_store(&own.stop, true);
		pthread_join(own.t, NULL);
	}
	if (own.h)
		cogw_close(own.h);
	sdo_req_fini(&q);
	if (fd >= 0)
		close(fd);
	bench_daemon_stop(&d);
	bench_unlink_instance_queues(instance);
	bench_tmpdir_remove(tmpdir);
	return status;
}
