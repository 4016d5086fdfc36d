/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: SDO through a real cogwd on vcan0 against a simulated device
 * (cosim, node 5, a device file written here).
 *
 *   - baseline: raw frame throughput of vcan0 (a sender writing 8-byte
 *     frames as fast as the line takes them, a receiver process counting
 *     what it gets, over a few seconds), and for context the kernel's can-gw
 *     forwarding vcan0 -> vcan1 where cangw(8) and the module are there;
 *   - SDO block upload of 1 MiB (libcogw -> cogwd -> cosim and back through
 *     the chunked mailbox answer), checked byte for byte; target >= 70 % of
 *     raw frames/s x 7 bytes;
 *   - segmented SDO upload: round-trip time per segment, against a raw CAN
 *     frame ping-pong between two processes on vcan0.
 */
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define NODE 5
#define BLOCK_INDEX 0x2F00
#define BLOCK_SIZE (1024u * 1024u)
#define SEG_INDEX 0x2F01
#define SEG_SIZE 700u /* 100 segments of 7 bytes */
#define RAW_ID 0x7AAu
#define ECHO_ID 0x7ABu

static char instance[32];
static char tmpdir[128];
static double run_seconds = 2.0;

static uint8_t pattern(uint32_t i)
{
	return (uint8_t)(i * 131u + (i >> 11));
}

/* ---- baselines on raw CAN ------------------------------------------------------- */

static int open_filtered(const char *ifname, uint32_t id)
{
	int fd = can_open_raw(ifname);
	if (fd < 0)
		return fd;
	struct can_filter f = { .can_id = id,
				.can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG };
	setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f);
	int big = 4 * 1024 * 1024;
	setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
	return fd;
}

/* A child counts frames with RAW_ID arriving on rx_if while the parent
 * writes them on tx_if for `seconds`. Returns received frames/s; *sent_rate
 * tells what the sender managed. */
static double frame_throughput(const char *tx_if, const char *rx_if, double seconds,
			       double *sent_rate)
{
	int counts[2];
	if (pipe(counts))
		return -1;
	int rx = open_filtered(rx_if, RAW_ID);
	int tx = can_open_raw(tx_if);
	if (rx < 0 || tx < 0) {
		printf("frame throughput: cannot open %s/%s\n", tx_if, rx_if);
		return -1;
	}
	fflush(stdout);
	pid_t child = fork();
	if (child == 0) {
		close(tx);
		/* counts until a frame with data[0] = 0xFF (the end mark) */
		uint64_t n = 0;
		double first = 0, last = 0;
		struct can_frame f;
		struct timeval tv = { 2, 0 };
		setsockopt(rx, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
		while (read(rx, &f, sizeof f) == (ssize_t)sizeof f) {
			if (f.data[0] == 0xFF)
				break;
			last = bench_now_s();
			if (!n++)
				first = last;
		}
		double rate = n > 1 && last > first ? (double)(n - 1) / (last - first) : 0;
		if (write(counts[1], &rate, sizeof rate) != (ssize_t)sizeof rate)
			_exit(1);
		_exit(0);
	}
	close(rx);
	uint8_t data[8] = { 0x01, 2, 3, 4, 5, 6, 7, 8 };
	uint64_t sent = 0;
	double t0 = bench_now_s(), end = t0 + seconds;
	while (bench_now_s() < end) {
		for (int i = 0; i < 64; i++) {
			if (can_send_std(tx, RAW_ID, data, 8) == 0)
				sent++;
		}
	}
	*sent_rate = (double)sent / (bench_now_s() - t0);
	sleep_ms(200); /* let the receiver drain what is queued before the mark */
	data[0] = 0xFF;
	for (int i = 0; i < 3; i++)
		can_send_std(tx, RAW_ID, data, 8);
	double rate = -1;
	if (read(counts[0], &rate, sizeof rate) != (ssize_t)sizeof rate)
		rate = -1;
	waitpid(child, NULL, 0);
	close(tx);
	close(counts[0]);
	close(counts[1]);
	return rate;
}

/* Raw frame ping-pong on vcan0: RAW_ID out, a child answers ECHO_ID. */
static double frame_pingpong_us(double seconds, int *samples)
{
	int a = open_filtered("vcan0", ECHO_ID), b = open_filtered("vcan0", RAW_ID);
	if (a < 0 || b < 0)
		return -1;
	fflush(stdout);
	pid_t child = fork();
	if (child == 0) {
		close(a);
		struct can_frame f;
		struct timeval tv = { 3, 0 };
		setsockopt(b, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
		while (read(b, &f, sizeof f) == (ssize_t)sizeof f && f.data[0] != 0xFF)
			can_send_std(b, ECHO_ID, f.data, f.can_dlc);
		_exit(0);
	}
	close(b);
	uint8_t data[8] = { 0 }, in[8];
	int n = 0;
	double total = 0, end = bench_now_s() + seconds;
	while (bench_now_s() < end) {
		uint64_t t0 = bench_now_ns();
		data[0] = (uint8_t)(n & 0x7F);
		if (can_send_std(a, RAW_ID, data, 8) < 0 || can_wait_id(a, ECHO_ID, in, 2000) < 0)
			break;
		total += (double)(bench_now_ns() - t0) * 1e-3;
		n++;
	}
	data[0] = 0xFF;
	can_send_std(a, RAW_ID, data, 8);
	waitpid(child, NULL, 0);
	close(a);
	*samples = n;
	return n ? total / n : -1;
}

/* Forwarding by the kernel's can-gw (context only): needs cangw(8), root
 * and the can-gw module. Returns frames/s received on vcan1, or -1. */
static double cangw_throughput(double seconds, double *sent_rate)
{
	if (system("cangw -A -s vcan0 -d vcan1 -e >/dev/null 2>&1") != 0)
		return -1;
	double rate = frame_throughput("vcan0", "vcan1", seconds, sent_rate);
	if (system("cangw -D -s vcan0 -d vcan1 -e >/dev/null 2>&1") != 0)
		printf("can-gw: could not remove the vcan0 -> vcan1 rule\n");
	return rate;
}

/* ---- the device and the daemon ------------------------------------------------- */

static int write_device(const char *path)
{
	size_t cap = 2u * BLOCK_SIZE + 2u * SEG_SIZE + 4096u;
	char *text = malloc(cap);
	if (!text)
		return -ENOMEM;
	static const char hex[] = "0123456789ABCDEF";
	size_t n = (size_t)snprintf(
		text, cap,
		"{\"name\": \"bench-domain\", \"node_id\": %d, \"heartbeat_ms\": 1000,\n"
		" \"objects\": [\n"
		"  {\"index\": \"0x%04X\", \"name\": \"1 MiB domain\", \"type\": \"DOMAIN\", "
		"\"access\": \"ro\",\n"
		"   \"max_size\": %u, \"default\": \"",
		NODE, BLOCK_INDEX, BLOCK_SIZE);
	for (uint32_t i = 0; i < BLOCK_SIZE; i++) {
		text[n++] = hex[pattern(i) >> 4];
		text[n++] = hex[pattern(i) & 15];
	}
	n += (size_t)snprintf(text + n, cap - n,
			      "\"},\n  {\"index\": \"0x%04X\", \"name\": \"segmented\", \"type\": "
			      "\"OCTET_STRING\", \"access\": \"ro\",\n"
			      "   \"max_size\": %u, \"default\": \"",
			      SEG_INDEX, SEG_SIZE);
	for (uint32_t i = 0; i < SEG_SIZE; i++) {
		text[n++] = hex[pattern(i + 7) >> 4];
		text[n++] = hex[pattern(i + 7) & 15];
	}
	snprintf(text + n, cap - n, "\"}]}\n");
	int rc = bench_write_file(path, text);
	free(text);
	return rc;
}

static int write_config(const char *path, unsigned depth)
{
	char text[2048];
	snprintf(text, sizeof text,
		 "{\"version\": 1, \"state_dir\": \"%s/state\",\n"
		 " \"mailbox\": {\"instance\": \"%s\", \"depth\": %u},\n"
		 " \"lines\": [{\"name\": \"bench0\", \"interface\": \"vcan0\", \"bitrate\": "
		 "1000000,\n"
		 "   \"node_id\": 127, \"sdo_timeout_ms\": 5000}]}\n",
		 tmpdir, instance, depth);
	return bench_write_file(path, text);
}

static cogw *client_open(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = instance, .timeout_ms = 10000 };
	int rc = cogw_open_opts(&h, &o);
	if (rc < 0) {
		printf("cogw_open: %s\n", cogw_strerror(rc));
		return NULL;
	}
	return h;
}

/* The device answers SDO once cosim runs: retry until it does. */
static int wait_device(cogw *h)
{
	for (uint64_t until = mono_ms() + 15000; mono_ms() < until; sleep_ms(100)) {
		uint32_t v = 0, abort = 0;
		if (cogw_sdo_read_u32(h, 0, NODE, 0x1000, 0, &v, 3000, &abort) == 0)
			return 0;
	}
	printf("bench_vcan_sdo: the simulated device does not answer SDO\n");
	return -1;
}

/* One SDO upload, timed and checked. Returns seconds, or -1. */
static double timed_upload(cogw *h, uint16_t index, uint8_t mode, uint8_t *buf, uint32_t size,
			   uint32_t offset)
{
	size_t len = 0;
	uint32_t abort = 0;
	cogw_sdo_opts o = { .mode = mode };
	memset(buf, 0, size);
	double t0 = bench_now_s();
	int rc = cogw_sdo_read_ex(h, 0, NODE, index, 0, &o, buf, size, &len, 300000, &abort);
	double took = bench_now_s() - t0;
	if (rc < 0) {
		printf("SDO upload %04X (mode %u): %s, abort %08X\n", index, mode,
		       cogw_strerror(rc), abort);
		return -1;
	}
	if (len != size) {
		printf("SDO upload %04X: %zu bytes instead of %u\n", index, len, size);
		return -1;
	}
	for (uint32_t i = 0; i < size; i++) {
		if (buf[i] != pattern(i + offset)) {
			printf("SDO upload %04X: byte %u is %02X, expected %02X\n", index, i,
			       buf[i], pattern(i + offset));
			return -1;
		}
	}
	return took;
}

int main(void)
{
	const char *secs = getenv("COGW_BENCH_SECONDS");
	if (secs && atof(secs) > 0)
		run_seconds = atof(secs);
	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "sdo") < 0)
		return 1;
	char cfg[256], dev[256], log[256], simlog[256], state[256], prog[256];
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(dev, sizeof dev, "%s/device.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(simlog, sizeof simlog, "%s/cosim.log", tmpdir);
	snprintf(state, sizeof state, "%s/state", tmpdir);
	unsigned msg_max = bench_mq_msg_max();
	uint8_t *buf = malloc(BLOCK_SIZE);
	bench_daemon d = { .pid = -1 };
	pid_t sim = -1;
	cogw *h = NULL;
	int status = 1;

	printf("bench_vcan_sdo: cogwd + cosim (node %d) on vcan0, %.1f s per raw measurement\n",
	       NODE, run_seconds);

	double sent_rate = 0;
	double raw_rate = frame_throughput("vcan0", "vcan0", run_seconds + 1, &sent_rate);
	if (raw_rate <= 0)
		goto out;
	bench_note("raw vcan0: a sender wrote %.0f frames/s, a receiver process got %.0f frames/s",
		   sent_rate, raw_rate);
	double gw_sent = 0, gw_rate = cangw_throughput(run_seconds, &gw_sent);
	if (gw_rate > 0)
		bench_print_figure(
			&(bench_figure){ .name = "kernel can-gw forwarding vcan0 to vcan1",
					 .value = gw_rate,
					 .unit = "frames/s",
					 .base_name = "raw vcan0 frame throughput",
					 .base_value = raw_rate,
					 .base_unit = "frames/s",
					 .ratio = gw_rate / raw_rate,
					 .target = "none (context)",
					 .verdict = "-" });
	else
		bench_note("kernel can-gw forwarding: not measured (needs cangw(8), root and the "
			   "can-gw module)");
	int pp_samples = 0;
	double pp_us = frame_pingpong_us(run_seconds, &pp_samples);

	if (!buf || write_device(dev) < 0 || write_config(cfg, msg_max < 64 ? msg_max : 64) < 0)
		goto out;
	const char *sim_argv[] = { bench_program("cosim", prog, sizeof prog),
				   "--interface",
				   "vcan0",
				   "--device",
				   dev,
				   "--quiet",
				   NULL };
	sim = proc_spawn(sim_argv, simlog, NULL);
	if (bench_daemon_start(&d, cfg, instance, log) < 0 || !(h = client_open()) ||
	    wait_device(h) < 0) {
		proc_dump_log(simlog, 10);
		goto out;
	}

	/* 1 MiB block upload: natively a few rounds, in the VM one (it is slow) */
	int rounds = bench_in_vm() ? 1 : 3;
	double best = 0;
	for (int r = 0; r < rounds; r++) {
		double s = timed_upload(h, BLOCK_INDEX, 3, buf, BLOCK_SIZE, 0);
		if (s < 0)
			goto out;
		if (best == 0 || s < best)
			best = s;
	}
	double block_bps = BLOCK_SIZE / best;
	double target_bps = raw_rate * 7.0;
	bench_print_figure(
		&(bench_figure){ .name = "SDO block upload 1 MiB from cosim (data bytes/s)",
				 .value = block_bps,
				 .unit = "B/s",
				 .base_name = "raw vcan0 frames/s x 7 bytes",
				 .base_value = target_bps,
				 .base_unit = "B/s",
				 .ratio = block_bps / target_bps,
				 .target = "ratio >= 0.80",
				 .verdict = bench_verdict(block_bps >= 0.80 * target_bps) });
	bench_note("block upload: best of %d round%s %.2f s for %u bytes (%u data frames), checked "
		   "byte for byte",
		   rounds, rounds == 1 ? "" : "s", best, BLOCK_SIZE, (BLOCK_SIZE + 6) / 7);

	/* segmented: SEG_SIZE bytes = 100 segments + the initiate exchange */
	unsigned segments = (SEG_SIZE + 6) / 7, transfers = 0;
	double total = 0, end = bench_now_s() + run_seconds;
	while (bench_now_s() < end || transfers < 3) {
		double s = timed_upload(h, SEG_INDEX, 2, buf, SEG_SIZE, 7);
		if (s < 0)
			goto out;
		total += s;
		transfers++;
	}
	double per_seg_us = total / transfers / segments * 1e6;
	bench_print_figure(&(bench_figure){ .name = "segmented SDO upload round trip per segment",
					    .value = per_seg_us,
					    .unit = "us",
					    .base_name = "raw CAN frame ping-pong on vcan0",
					    .base_value = pp_us,
					    .base_unit = "us",
					    .ratio = pp_us > 0 ? per_seg_us / pp_us : -1,
					    .target = "none (context)",
					    .verdict = "-" });
	bench_note("segmented: %u uploads of %u bytes (%u segments each, initiate and mailbox "
		   "included); %d raw ping-pongs",
		   transfers, SEG_SIZE, segments, pp_samples);
	status = 0;
out:
	cogw_close(h);
	bench_daemon_stop(&d);
	if (sim > 0)
		proc_stop(sim, SIGTERM, 5000);
	bench_unlink_instance_queues(instance);
	bench_tmpdir_remove(state);
	bench_tmpdir_remove(tmpdir);
	free(buf);
	return status;
}
