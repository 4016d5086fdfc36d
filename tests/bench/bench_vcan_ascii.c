/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the CiA 309-3 ASCII gateway (cogw-ascii) against libcogw, in
 * the same run, through a real cogwd and cosim on vcan0 (docs/ascii.md).
 *
 *   - one "r" of an expedited object (1018h:04 u32) over the UNIX socket,
 *     request then answer, against the same read through libcogw
 *     (cogw_sdo_read_u32) from this process (target: <= 1.3x);
 *   - 16 connections reading at once (each to one of 16 simulated nodes,
 *     one request at a time) against one connection: aggregate reads/s
 *     (target: >= 4x, bounded by the bus and the line's SDO clients).
 *
 * Needs vcan0 and the release cogwd, cosim and cogw-ascii: run through
 * tests/bench/run-vcan (make bench). Prints figures; asserts nothing, but
 * says so loudly when an answer is wrong.
 */
#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define FIRST_NODE 5
#define NODES 16
#define CONNS 16

static char instance[32], tmpdir[64], sock_path[100];
static double run_seconds = 3.0;

static int write_config(const char *path)
{
	char text[1024];

	snprintf(text, sizeof text,
		 "{\"version\": 1, \"state_dir\": \"%s/state\","
		 " \"mailbox\": {\"instance\": \"%s\", \"max_outstanding\": 32},"
		 " \"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127,"
		 " \"network_id\": 1, \"sdo_clients\": 16}]}",
		 tmpdir, instance);
	return bench_write_file(path, text);
}

static int connect_gateway(void)
{
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

	snprintf(a.sun_path, sizeof a.sun_path, "%s", sock_path);
	if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0)
		return fd;
	if (fd >= 0)
		close(fd);
	return -1;
}

/* One command, its one answer line; 0 if it is `want`. */
static int ask(int fd, const char *cmd, size_t cmd_len, const char *want)
{
	char buf[256];
	size_t len = 0;

	if (send(fd, cmd, cmd_len, MSG_NOSIGNAL) != (ssize_t)cmd_len)
		return -1;
	while (!memchr(buf, '\n', len)) {
		ssize_t k = recv(fd, buf + len, sizeof buf - 1 - len, 0);

		if (k <= 0)
			return -1;
		len += (size_t)k;
	}
	buf[len] = '\0';
	return strcmp(buf, want) == 0 ? 0 : -1;
}

typedef struct reader {
	pthread_t t;
	int fd;
	unsigned node;
	double until;
	unsigned long reads;
	bool failed;
} reader;

static void *reader_run(void *arg)
{
	reader *r = arg;
	char cmd[64];
	int n = snprintf(cmd, sizeof cmd, "1 %u r 0x1018 4 u32\n", r->node);

	while (bench_now_s() < r->until) {
		if (ask(r->fd, cmd, (size_t)n, "4242\r\n") < 0) {
			r->failed = true;
			break;
		}
		r->reads++;
	}
	return NULL;
}

/* Aggregate reads/s of n connections reading at once for run_seconds. */
static double socket_rate(unsigned n)
{
	reader rs[CONNS];
	double t0, until, took;
	unsigned long total = 0;

	for (unsigned i = 0; i < n; i++) {
		rs[i] = (reader){ .fd = connect_gateway(), .node = FIRST_NODE + i % NODES };
		if (rs[i].fd < 0)
			return -1;
	}
	t0 = bench_now_s();
	until = t0 + run_seconds;
	for (unsigned i = 0; i < n; i++) {
		rs[i].until = until;
		pthread_create(&rs[i].t, NULL, reader_run, &rs[i]);
	}
	for (unsigned i = 0; i < n; i++) {
		pthread_join(rs[i].t, NULL);
		close(rs[i].fd);
		total += rs[i].reads;
		if (rs[i].failed) {
			printf("bench_vcan_ascii: a wrong or missing answer on connection %u\n", i);
			return -1;
		}
	}
	took = bench_now_s() - t0;
	return (double)total / took;
}

/* Mean seconds of one read through libcogw, over run_seconds. */
static double libcogw_read_s(cogw *h)
{
	double t0 = bench_now_s();
	unsigned long n = 0;

	while (bench_now_s() - t0 < run_seconds) {
		uint32_t v = 0, abort = 0;

		if (cogw_sdo_read_u32(h, 0, FIRST_NODE, 0x1018, 4, &v, 5000, &abort) < 0 ||
		    v != 4242) {
			printf("bench_vcan_ascii: libcogw read failed (abort %08X)\n", abort);
			return -1;
		}
		n++;
	}
	return (bench_now_s() - t0) / (double)n;
}

int main(void)
{
	const char *secs = getenv("COGW_BENCH_SECONDS");
	char cfg[256], log[256], simlog[256], gwlog[256], prog[256], prog2[256];
	char devs[NODES][160];
	const char *sim_argv[4 + 2 * NODES + 1];
	bench_daemon d = { .pid = -1 };
	pid_t sim = -1, gw = -1;
	cogw *h = NULL;
	int status = 1, k = 0;

	if (secs && atof(secs) > 0)
		run_seconds = atof(secs);
	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "ascii") < 0)
		return 1;
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(simlog, sizeof simlog, "%s/cosim.log", tmpdir);
	snprintf(gwlog, sizeof gwlog, "%s/ascii.log", tmpdir);
	snprintf(sock_path, sizeof sock_path, "%s/ascii.sock", tmpdir);
	printf("bench_vcan_ascii: cogwd + cosim (%d nodes) + cogw-ascii on vcan0, %.1f s per "
	       "measurement\n",
	       NODES, run_seconds);
	if (write_config(cfg) < 0)
		goto out;
	sim_argv[k++] = bench_program("cosim", prog, sizeof prog);
	sim_argv[k++] = "--interface";
	sim_argv[k++] = "vcan0";
	for (int i = 0; i < NODES; i++) {
		snprintf(devs[i], sizeof devs[i], "tests/integration/config/ascii-types.json:%d",
			 FIRST_NODE + i);
		sim_argv[k++] = "--device";
		sim_argv[k++] = devs[i];
	}
	sim_argv[k++] = "--quiet";
	sim_argv[k] = NULL;
	sim = proc_spawn(sim_argv, simlog, NULL);
	if (bench_daemon_start(&d, cfg, instance, log) < 0)
		goto out;
	const char *gw_argv[] = { bench_program("cogw-ascii", prog2, sizeof prog2),
				  "--daemon-config",
				  cfg,
				  "--socket",
				  sock_path,
				  NULL };

	gw = proc_spawn(gw_argv, gwlog, NULL);
	if (!file_wait_contains(gwlog, "serving instance", 10000) || cogw_open(&h, instance) < 0) {
		proc_dump_log(gwlog, 10);
		goto out;
	}
	/* the devices answer once cosim runs */
	for (uint64_t until = mono_ms() + 15000; mono_ms() < until; sleep_ms(100)) {
		uint32_t v = 0, abort = 0;

		if (cogw_sdo_read_u32(h, 0, FIRST_NODE + NODES - 1, 0x1018, 4, &v, 3000, &abort) ==
		    0)
			break;
	}
	double lib_s = libcogw_read_s(h);
	double one = socket_rate(1);
	double many = socket_rate(CONNS);

	if (lib_s <= 0 || one <= 0 || many <= 0)
		goto out;
	double sock_s = 1.0 / one;

	bench_print_figure(&(bench_figure){ .name = "cogw-ascii r 1018h:04 u32, one connection",
					    .value = sock_s * 1e6,
					    .unit = "us",
					    .base_name = "the same read through libcogw",
					    .base_value = lib_s * 1e6,
					    .base_unit = "us",
					    .ratio = sock_s / lib_s,
					    .target = "ratio <= 1.30",
					    .verdict = bench_verdict(sock_s / lib_s <= 1.3) });
	bench_print_figure(&(bench_figure){ .name = "cogw-ascii 16 connections aggregate",
					    .value = many,
					    .unit = "reads/s",
					    .base_name = "one connection",
					    .base_value = one,
					    .base_unit = "reads/s",
					    .ratio = many / one,
					    .target = "ratio >= 4.00",
					    .verdict = bench_verdict(many / one >= 4.0) });
	status = 0;
out:
	cogw_close(h);
	if (gw > 0)
		proc_stop(gw, 15, 5000);
	bench_daemon_stop(&d);
	if (sim > 0)
		proc_stop(sim, 15, 5000);
	bench_tmpdir_remove(tmpdir);
	return status;
}
