/* SPDX-License-Identifier: MIT */
/*
 * Micro-benchmark: a 1 MiB SDO block transfer (download, then upload, with
 * CRC) between two core instances wired in memory. Prints frames/s,
 * bytes/s and CPU ns per frame beside the target; asserts nothing.
 *
 * Target (docs/testing.md): <= 1 us of CPU per frame, so that one core carries
 * 8 lines at full 1 Mbit/s load (about 9,000 frames/s each) with < 10 %
 * of one CPU. "Per frame" here is everything one frame costs in this
 * process: the sender's core, the in-memory hop and the receiver's core.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/co.h"
#include "core/sdo_client.h"

#define SIZE (1024u * 1024u)
#define ROUNDS 5
#define QCAP 4096u

struct bus {
	co_frame q[QCAP];
	int from[QCAP];
	unsigned head, len;
	co_node *node[2];
	uint64_t frames;
	uint64_t now;
};

struct port {
	struct bus *bus;
	int idx;
};

static int bus_send(void *ctx, const co_frame *f)
{
	struct port *p = ctx;
	struct bus *b = p->bus;

	if (b->len == QCAP)
		return -ENOBUFS;
	unsigned pos = (b->head + b->len) % QCAP;
	b->q[pos] = *f;
	b->from[pos] = p->idx;
	b->len++;
	return 0;
}

static int done_count;
static uint32_t last_abort;

static void on_event(void *ctx, const co_event *ev)
{
	(void)ctx;
	if (ev->kind == CO_EV_SDO_CLIENT_DONE) {
		done_count++;
		last_abort = ev->u.sdo_cli.abort;
	}
}

static void pump(struct bus *b)
{
	while (b->len) {
		co_frame f = b->q[b->head];
		int to = 1 - b->from[b->head];
		b->head = (b->head + 1) % QCAP;
		b->len--;
		b->frames++;
		co_node_recv(b->node[to], &f, b->now);
	}
}

static double cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static double wall_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void report(const char *what, uint64_t frames, uint64_t bytes, double cpu, double wall)
{
	double ns = cpu * 1e9 / (double)frames;
	double load8 = 8.0 * 9000.0 * ns * 1e-9 * 100.0;

	printf("%-16s %9.0f frames/s %8.1f MB/s %7.1f ns CPU/frame "
	       "(target <= 1000 ns) -> 8 lines x 9000 frames/s = %.2f %% of one CPU "
	       "(target < 10 %%)  [%llu frames, %.3f s]\n",
	       what, (double)frames / wall, (double)bytes / wall / 1e6, ns, load8,
	       (unsigned long long)frames, wall);
}

int main(void)
{
	static struct bus bus;
	struct port ps = { &bus, 0 }, pc = { &bus, 1 };
	co_od *sod, *cod;
	co_od_entry *dom;
	uint8_t *src = malloc(SIZE), *dst = malloc(SIZE);

	if (!src || !dst || co_od_create(&sod, 16) || co_od_create(&cod, 16))
		return 1;
	for (uint32_t i = 0; i < SIZE; i++)
		src[i] = (uint8_t)(i * 131u + (i >> 11));
	if (co_od_add_bytes(sod, 0x2200, 0, CO_T_DOMAIN, CO_ACC_RW, SIZE, NULL, 0, &dom))
		return 1;

	co_node_config sc = {
		.node_id = 5, .od = sod, .send = bus_send, .send_ctx = &ps, .event = on_event
	};
	co_node_config cc = { .node_id = 1,
			      .od = cod,
			      .send = bus_send,
			      .send_ctx = &pc,
			      .event = on_event,
			      .sdo_client_count = 1 };
	if (co_node_create(&bus.node[0], &sc) || co_node_create(&bus.node[1], &cc))
		return 1;

	printf("bench_sdo_block: %u KiB block transfer with CRC, 2 core instances in memory, "
	       "%d rounds each way\n",
	       SIZE / 1024, ROUNDS);
	for (int dir = 0; dir < 2; dir++) {
		uint64_t frames0 = bus.frames;
		double c0 = cpu_s(), w0 = wall_s();
		for (int r = 0; r < ROUNDS; r++) {
			sdo_client_req req = { .upload = dir == 1,
					       .node_id = 5,
					       .index = 0x2200,
					       .mode = SDO_MODE_BLOCK,
					       .timeout_ms = 1000 };
			if (dir == 0) {
				req.data = src;
				req.size = SIZE;
			} else {
				req.buf = dst;
				req.cap = SIZE;
			}
			int before = done_count;
			if (sdo_client_submit(bus.node[1], 0, &req, bus.now))
				return 1;
			pump(&bus);
			if (done_count != before + 1 || last_abort) {
				printf("transfer failed: abort %08X\n", last_abort);
				return 1;
			}
			bus.now += 1000;
		}
		double c1 = cpu_s(), w1 = wall_s();
		report(dir == 0 ? "block download" : "block upload", bus.frames - frames0,
		       (uint64_t)SIZE * ROUNDS, c1 - c0, w1 - w0);
	}
	if (memcmp(src, dst, SIZE) != 0 || dom->size != SIZE || memcmp(src, dom->data, SIZE))
		printf("WARNING: data mismatch\n");
	co_node_destroy(bus.node[0]);
	co_node_destroy(bus.node[1]);
	co_od_destroy(sod);
	co_od_destroy(cod);
	free(src);
	free(dst);
	return 0;
}
