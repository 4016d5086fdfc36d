/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the CiA 302-2 network boot of a real cogwd on vcan0 with 1, 8
 * and 32 simulated devices (cosim, at most 16 nodes per process).
 *
 * For each size N:
 *   - baseline: the boot's SDO reads done raw, one after the other, by this
 *     process on vcan0 against the same devices before the daemon runs
 *     (5 expedited uploads per node: 1000h and 1018h:1..4, what the
 *     manager reads to check device type and identity);
 *   - the boot: cogwd's manager boots the line again on a mailbox request
 *     (reset communication of all nodes, boot-ups, the five reads per node,
 *     NMT start of each node); the time from the request to the manager's
 *     "operational" event with all N booted, best of a few rounds. The
 *     frames of the boot (NMT, SDO, boot-ups) are counted on the bus.
 * Target (docs/testing.md): 32 nodes boot in at most 1.5 x the boot of one node
 * plus the bus time of the 32-node boot's frames at the line's 1 Mbit/s
 * (47 + 8 x DLC bits per standard frame, without stuffing). The line's SDO
 * client pool (sdo_clients) is 32, so that the manager may boot every node
 * at once; the default pool of 4 is measured with 32 nodes for context.
 */
#include <errno.h>
#include <linux/can.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/manager.h"
#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define MAX_DEV 32
#define PER_SIM 16 /* cosim's limit of nodes per process */
#define READS_PER_NODE 5
#define BITRATE 1000000.0
#define ROUNDS 5 /* boots (and raw baselines) per size: the best counts */

static char instance[32];
static char tmpdir[128];

typedef struct boot_run {
	double seconds;  /* best time of the rounds */
	unsigned frames; /* frames of that round */
	double bus_s;    /* their bus time at BITRATE */
} boot_run;

static int write_device(const char *path)
{
	return bench_write_file(
		path,
		"{\"name\": \"bench-slave\", \"node_id\": 1, \"device_type\": \"0x000F0191\",\n"
		" \"identity\": {\"vendor\": \"0x00001234\", \"product\": \"0x00000401\",\n"
		"   \"revision\": \"0x00010000\", \"serial\": 4711}}\n");
}

/* The line's manager knows nodes 1..n with their full identity; no error
 * control (the boot is measured, not a heartbeat period). */
static int write_config(const char *path, unsigned n, unsigned sdo_clients)
{
	char text[16384];
	size_t len = (size_t)snprintf(
		text, sizeof text,
		"{\"version\": 1, \"state_dir\": \"%s/state\",\n"
		" \"mailbox\": {\"instance\": \"%s\"},\n"
		" \"lines\": [{\"name\": \"bench0\", \"interface\": \"vcan0\", \"bitrate\": "
		"1000000,\n"
		"   \"node_id\": 127, \"sdo_clients\": %u,\n"
		"   \"manager\": {\"boot_time_ms\": 0, \"sdo_timeout_ms\": 2000},\n"
		"   \"nodes\": [",
		tmpdir, instance, sdo_clients);
	for (unsigned id = 1; id <= n && len < sizeof text; id++)
		len += (size_t)snprintf(
			text + len, sizeof text - len,
			"%s\n    {\"id\": %u, \"mandatory\": true, "
			"\"device_type\": \"0x000F0191\", \"vendor_id\": \"0x1234\", "
			"\"product_code\": \"0x401\", \"revision\": \"0x10000\", "
			"\"serial\": 4711}",
			id == 1 ? "" : ",", id);
	if (len >= sizeof text - 8)
		return -ENOSPC;
	snprintf(text + len, sizeof text - len, "]}]}\n");
	return bench_write_file(path, text);
}

/* cosim processes with nodes 1..n (PER_SIM each). */
static int start_devices(pid_t *sims, unsigned n, const char *dev, char devs[][300])
{
	char prog[256];
	for (unsigned first = 1, k = 0; first <= n; first += PER_SIM, k++) {
		const char *argv[3 + 2 * PER_SIM + 2];
		unsigned argc = 0;
		argv[argc++] = bench_program("cosim", prog, sizeof prog);
		argv[argc++] = "--interface";
		argv[argc++] = "vcan0";
		for (unsigned id = first; id <= n && id < first + PER_SIM; id++) {
			snprintf(devs[id], sizeof devs[id], "%s:%u", dev, id);
			argv[argc++] = "--device";
			argv[argc++] = devs[id];
		}
		argv[argc++] = "--quiet";
		argv[argc] = NULL;
		char log[300];
		snprintf(log, sizeof log, "%s/cosim%u.log", tmpdir, k);
		sims[k] = proc_spawn(argv, log, NULL);
		if (sims[k] < 0)
			return -1;
	}
	return 0;
}

static void stop_devices(pid_t *sims, unsigned n)
{
	for (unsigned k = 0; k * PER_SIM < n; k++)
		if (sims[k] > 0)
			proc_stop(sims[k], SIGTERM, 5000);
}

/* One raw expedited upload to node `id`: 0 or -1 (no answer). */
static int raw_read(int fd, uint8_t id, uint16_t index, uint8_t sub)
{
	uint8_t req[8] = { 0x40, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0 }, ans[8];
	if (can_send_std(fd, 0x600u + id, req, 8) < 0)
		return -1;
	return can_wait_id(fd, 0x580u + id, ans, 2000) == 8 && (ans[0] & 0xE0) == 0x40 ? 0 : -1;
}

static const uint8_t id_subs[READS_PER_NODE] = { 0, 1, 2, 3, 4 };

/* The boot's reads, raw and one after the other; best of `rounds`. */
static double raw_baseline(unsigned n, int rounds)
{
	int fd = can_open_raw("vcan0");
	double best = -1;
	if (fd < 0)
		return -1;
	/* the devices answer once they are up */
	uint64_t until = mono_ms() + 15000;
	for (unsigned id = 1; id <= n; id++)
		while (raw_read(fd, (uint8_t)id, 0x1000, 0) < 0)
			if (mono_ms() > until) {
				printf("bench_vcan_manager: node %u does not answer SDO\n", id);
				close(fd);
				return -1;
			}
	for (int r = 0; r < rounds; r++) {
		double t0 = bench_now_s();
		for (unsigned id = 1; id <= n; id++)
			for (unsigned k = 0; k < READS_PER_NODE; k++)
				if (raw_read(fd, (uint8_t)id, k ? 0x1018 : 0x1000, id_subs[k]) <
				    0) {
					printf("raw SDO read of node %u failed\n", id);
					close(fd);
					return -1;
				}
		double s = bench_now_s() - t0;
		if (best < 0 || s < best)
			best = s;
	}
	close(fd);
	return best;
}

/* Frames of the boot in the socket: NMT, SDO requests/answers, boot-ups. */
static void count_boot_frames(int fd, unsigned *frames, double *bits)
{
	struct can_frame f;
	while (recv(fd, &f, sizeof f, MSG_DONTWAIT) == (ssize_t)sizeof f) {
		uint32_t id = f.can_id & CAN_SFF_MASK;
		bool boot_frame = id == 0 || (id >= 0x581 && id <= 0x67F) ||
				  (id > 0x700 && id < 0x780 && f.len == 1 && f.data[0] == 0);
		if (!boot_frame)
			continue;
		(*frames)++;
		*bits += 47.0 + 8.0 * f.len;
	}
}

/* Wait for the manager's "operational" event that follows a state other
 * than operational (the boot requested just before). */
static int wait_operational(cogw *h, bool *left, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	while (mono_ms() < until) {
		cogw_msg m;
		if (cogw_recv(h, &m, 200) != 0)
			continue;
		bool done = false;
		if (m.code == MBX_EV_MGR_STATE && m.line == 0) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			if (e.state != CO_MGR_OPERATIONAL)
				*left = true;
			else if (*left)
				done = true;
		}
		cogw_msg_release(&m);
		if (done)
			return 0;
	}
	return -1;
}

static unsigned booted_count(cogw *h)
{
	mbx_mgr_status st;
	unsigned n = 0;
	if (cogw_mgr_status(h, 0, &st, 5000) != 0)
		return 0;
	for (unsigned i = 1; i < 128; i++)
		n += (st.booted.w[i / 32] >> (i % 32)) & 1u;
	return n;
}

/* cogwd with n nodes: the network boot requested `rounds` times. */
static int manager_boot(unsigned n, unsigned sdo_clients, int rounds, boot_run *out)
{
	char cfg[256], log[256];
	bench_daemon d = { .pid = -1 };
	cogw *h = NULL;
	int rc = -1, fd = -1;
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	if (write_config(cfg, n, sdo_clients) < 0 || bench_daemon_start(&d, cfg, instance, log) < 0)
		goto out;
	cogw_options o = { .instance = instance, .timeout_ms = 10000 };
	if (cogw_open_opts(&h, &o) < 0 || cogw_subscribe(h, 0, MBX_EVC_MANAGER, NULL, 0, 5000) != 0)
		goto out;
	/* the first boot, at the daemon's start */
	for (uint64_t until = mono_ms() + 30000; booted_count(h) < n; sleep_ms(50))
		if (mono_ms() > until) {
			printf("bench_vcan_manager: the first boot of %u nodes did not end\n", n);
			proc_dump_log(log, 20);
			goto out;
		}
	fd = can_open_raw("vcan0");
	int big = 4 * 1024 * 1024;
	if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &big, sizeof big) < 0)
		goto out;
	out->seconds = -1;
	for (int r = 0; r < rounds; r++) {
		unsigned frames = 0;
		double bits = 0;
		bool left = false;
		sleep_ms(300); /* the previous boot's NMT starts have settled */
		count_boot_frames(fd, &frames, &bits);
		frames = 0;
		bits = 0;
		double t0 = bench_now_s();
		if (cogw_mgr_boot(h, 0, 0, 5000) != 0 || wait_operational(h, &left, 60000) != 0) {
			printf("bench_vcan_manager: boot %d of %u nodes did not end\n", r, n);
			goto out;
		}
		double s = bench_now_s() - t0;
		count_boot_frames(fd, &frames, &bits);
		if (booted_count(h) != n) {
			printf("bench_vcan_manager: %u of %u nodes booted\n", booted_count(h), n);
			goto out;
		}
		if (out->seconds < 0 || s < out->seconds) {
			out->seconds = s;
			out->frames = frames;
			out->bus_s = bits / BITRATE;
		}
	}
	rc = 0;
out:
	if (fd >= 0)
		close(fd);
	cogw_close(h);
	bench_daemon_stop(&d);
	return rc;
}

static int measure(unsigned n, unsigned sdo_clients, const char *dev, boot_run *boot, double *raw_s)
{
	pid_t sims[MAX_DEV / PER_SIM + 1] = { 0 };
	static char devs[MAX_DEV + 1][300];
	int rc = -1;
	if (start_devices(sims, n, dev, devs) == 0 && (*raw_s = raw_baseline(n, ROUNDS)) > 0)
		rc = manager_boot(n, sdo_clients, ROUNDS, boot);
	stop_devices(sims, n);
	return rc;
}

int main(void)
{
	static const unsigned sizes[] = { 1, 8, 32 };
	boot_run boot[3] = { 0 }, boot_pool4 = { 0 };
	double raw[3] = { 0 }, raw_pool4 = 0;
	char dev[256], state[256];
	int status = 1;

	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "mgr") < 0)
		return 1;
	snprintf(dev, sizeof dev, "%s/slave.json", tmpdir);
	snprintf(state, sizeof state, "%s/state", tmpdir);
	printf("bench_vcan_manager: cogwd's CiA 302-2 manager boots 1, 8, 32 cosim nodes on "
	       "vcan0\n");
	if (write_device(dev) < 0)
		goto out;
	for (unsigned i = 0; i < 3; i++) {
		if (measure(sizes[i], MAX_DEV, dev, &boot[i], &raw[i]) < 0)
			goto out;
		char name[96], base[96];
		snprintf(name, sizeof name, "manager network boot of %u node%s", sizes[i],
			 sizes[i] == 1 ? "" : "s");
		snprintf(base, sizeof base, "%u raw SDO round trips one after the other",
			 sizes[i] * READS_PER_NODE);
		bench_print_figure(&(bench_figure){ .name = name,
						    .value = boot[i].seconds * 1e3,
						    .unit = "ms",
						    .base_name = base,
						    .base_value = raw[i] * 1e3,
						    .base_unit = "ms",
						    .ratio = boot[i].seconds / raw[i],
						    .target = "none (context)",
						    .verdict = "-" });
		bench_note("%u node%s: %u boot frames (NMT, SDO, boot-ups), %.2f ms of bus time at "
			   "1 Mbit/s",
			   sizes[i], sizes[i] == 1 ? "" : "s", boot[i].frames, boot[i].bus_s * 1e3);
	}
	double limit = 1.5 * boot[0].seconds + boot[2].bus_s;
	bench_print_figure(
		&(bench_figure){ .name = "manager network boot of 32 nodes against the boot of 1",
				 .value = boot[2].seconds * 1e3,
				 .unit = "ms",
				 .base_name = "1.5 x boot of 1 node + bus time of the 32-node boot",
				 .base_value = limit * 1e3,
				 .base_unit = "ms",
				 .ratio = boot[2].seconds / limit,
				 .target = "ratio <= 1.00",
				 .verdict = bench_verdict(boot[2].seconds <= limit) });
	if (measure(MAX_DEV, 4, dev, &boot_pool4, &raw_pool4) < 0)
		goto out;
	bench_print_figure(&(bench_figure){
		.name = "manager network boot of 32 nodes with the default pool of 4 SDO clients",
		.value = boot_pool4.seconds * 1e3,
		.unit = "ms",
		.base_name = "the same boot with a pool of 32",
		.base_value = boot[2].seconds * 1e3,
		.base_unit = "ms",
		.ratio = boot_pool4.seconds / boot[2].seconds,
		.target = "none (context)",
		.verdict = "-" });
	bench_note("each boot: best of %d rounds, from the mailbox request to the manager's "
		   "operational event; the raw baselines ran before the daemon, on the same "
		   "devices",
		   ROUNDS);
	status = 0;
out:
	bench_unlink_instance_queues(instance);
	bench_tmpdir_remove(state);
	bench_tmpdir_remove(tmpdir);
	return status;
}
