/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the CiA 309-3 ASCII gateway (cogw-ascii) against libcogw, in
 * the same run, through a real cogwd and cosim on vcan0 (docs/ascii.md).
 *
 *   - one "r" of an expedited object (1018h:04 u32) over the UNIX socket,
 *     request then answer, against the same read through libcogw
 *     (cogw_sdo_read_u32) from this process: p50 over every read (target:
 *     <= 1.3x);
 *   - 16 connections reading at once (each to one of 16 simulated nodes,
 *     one request at a time) against one connection: aggregate reads/s
 *     (target: >= 4x, bounded by the bus and the line's SDO clients).
 * Both in ROUNDS interleaved rounds, so that the host's load falls on
 * every side alike.
 *
 * COGW_BENCH_CANOPEND=PATH adds notes against the reference 309-3 gateway,
 * CANopenNode's canopend built by hand (reference_notes).
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

static int connect_path(const char *path)
{
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

	snprintf(a.sun_path, sizeof a.sun_path, "%s", path);
	if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0)
		return fd;
	if (fd >= 0)
		close(fd);
	return -1;
}

static int connect_gateway(void)
{
	return connect_path(sock_path);
}

/* Up to want answer lines (each ending in LF) into buf, waiting at most
 * 10 s for each piece: the number of lines, -1 on a close or silence. */
static int read_lines(int fd, char *buf, size_t cap, size_t *len, int want)
{
	int lines = 0;

	*len = 0;
	while (lines < want) {
		struct pollfd pf = { .fd = fd, .events = POLLIN };

		if (*len + 1 >= cap || poll(&pf, 1, 10000) <= 0)
			return -1;
		ssize_t k = recv(fd, buf + *len, cap - 1 - *len, 0);

		if (k <= 0)
			return -1;
		for (ssize_t i = 0; i < k; i++)
			lines += buf[*len + (size_t)i] == '\n';
		*len += (size_t)k;
	}
	buf[*len] = '\0';
	return lines;
}

/* One command, its one answer line: 0 if it is `want`, -2 another answer
 * (printed), -1 none. */
static int ask(int fd, const char *cmd, size_t cmd_len, const char *want)
{
	char buf[256];
	size_t len;

	if (send(fd, cmd, cmd_len, MSG_NOSIGNAL) != (ssize_t)cmd_len ||
	    read_lines(fd, buf, sizeof buf, &len, 1) != 1)
		return -1;
	if (strcmp(buf, want) == 0)
		return 0;
	printf("bench_vcan_ascii: '%.*s' answered '%.*s'\n", (int)strcspn(cmd, "\n"), cmd,
	       (int)strcspn(buf, "\r\n"), buf);
	return -2;
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

/* Aggregate reads/s of n connections reading at once for seconds. */
static double socket_rate(unsigned n, double seconds)
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
	until = t0 + seconds;
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

/* Reads through one kept connection, one at a time, for seconds: the
 * times (us) of those answered right appended to lat (at most max in all,
 * *n so far). -1 when an answer is missing. */
static int socket_reads(const char *path, const char *cmd, const char *want, double seconds,
			double *lat, size_t max, size_t *n)
{
	int fd = connect_path(path);
	size_t len = strlen(cmd);
	double end = bench_now_s() + seconds;
	int rc = fd < 0 ? -1 : 0;

	while (rc >= 0 && *n < max && bench_now_s() < end) {
		uint64_t t0 = bench_now_ns();

		rc = ask(fd, cmd, len, want);
		if (rc == 0) /* a wrong answer (printed) is no read */
			lat[(*n)++] = (double)(bench_now_ns() - t0) * 1e-3;
	}
	if (fd >= 0)
		close(fd);
	if (rc == -1)
		printf("bench_vcan_ascii: %s: no answer to '%.*s'\n", path, (int)strcspn(cmd, "\n"),
		       cmd);
	return rc == -1 ? -1 : 0;
}

/* The same read through libcogw, the same way. */
static int libcogw_reads(cogw *h, double seconds, double *lat, size_t max, size_t *n)
{
	double end = bench_now_s() + seconds;

	while (*n < max && bench_now_s() < end) {
		uint32_t v = 0, abort = 0;
		uint64_t t0 = bench_now_ns();

		if (cogw_sdo_read_u32(h, 0, FIRST_NODE, 0x1018, 4, &v, 5000, &abort) < 0 ||
		    v != 4242) {
			printf("bench_vcan_ascii: libcogw read failed (abort %08X)\n", abort);
			return -1;
		}
		lat[(*n)++] = (double)(bench_now_ns() - t0) * 1e-3;
	}
	return 0;
}

/* Of the answer lines in text, those that are not `want`: counted, the
 * first printed. */
static int wrong_answers(const char *path, char *text, const char *want)
{
	int wrong = 0;

	for (char *save = NULL, *l = strtok_r(text, "\n", &save); l;
	     l = strtok_r(NULL, "\n", &save)) {
		if (strncmp(l, want, strcspn(want, "\r\n")) == 0)
			continue;
		if (wrong++ == 0)
			printf("bench_vcan_ascii: %s: an answer of many at once: '%.*s'\n", path,
			       (int)strcspn(l, "\r"), l);
	}
	return wrong;
}

/* count reads written at once on a new connection: right answers per
 * second from the write to the last answer (a wrong one is printed and not
 * counted), -1 when answers are missing. */
static double burst_rate(const char *path, const char *cmd, const char *want, int count)
{
	size_t clen = strlen(cmd), cap = (size_t)count * 128;
	char *out = malloc((size_t)count * clen), *in = malloc(cap);
	int fd = connect_path(path), lines = -1;
	size_t len = 0;
	double took = 0;

	if (out && in && fd >= 0) {
		for (int i = 0; i < count; i++)
			memcpy(out + (size_t)i * clen, cmd, clen);
		double t0 = bench_now_s();

		if (send(fd, out, (size_t)count * clen, MSG_NOSIGNAL) ==
		    (ssize_t)((size_t)count * clen))
			lines = read_lines(fd, in, cap, &len, count);
		took = bench_now_s() - t0;
	}
	if (lines != count)
		printf("bench_vcan_ascii: %s: %d of %d reads written at once answered\n", path,
		       lines, count);
	else
		lines -= wrong_answers(path, in, want);
	if (fd >= 0)
		close(fd);
	free(out);
	free(in);
	return lines > 0 && took > 0 ? lines / took : -1;
}

/* ---- cogw-ascii against libcogw (make bench) ---------------------------------------- */

#define ROUNDS 5
#define LAT_MAX 200000

/* The median of the rounds' values, which stay in their order. */
static double median(const double v[ROUNDS])
{
	double c[ROUNDS];

	memcpy(c, v, sizeof c);
	return bench_percentile(c, ROUNDS, 50);
}

static double lib_lat[LAT_MAX], sock_lat[LAT_MAX];

/* ROUNDS rounds, each: reads through libcogw, the same reads through one
 * cogw-ascii connection, 1 and 16 connections at once (host load falls on
 * all of them alike); the figures are p50s over every round's reads and
 * the medians of the rounds' rates. */
static int ascii_figures(cogw *h)
{
	static const char cmd[] = "1 5 r 0x1018 4 u32\n";
	double one[ROUNDS], many[ROUNDS], slice = run_seconds / ROUNDS;
	size_t nl = 0, ns = 0;

	for (int r = 0; r < ROUNDS; r++) {
		/* in turns first, so that a trend of the host's load favours neither */
		bool lib_first = r % 2 == 0;

		if ((lib_first && libcogw_reads(h, slice, lib_lat, LAT_MAX, &nl) < 0) ||
		    socket_reads(sock_path, cmd, "4242\r\n", slice, sock_lat, LAT_MAX, &ns) < 0 ||
		    (!lib_first && libcogw_reads(h, slice, lib_lat, LAT_MAX, &nl) < 0))
			return -1;
		one[r] = socket_rate(1, slice);
		many[r] = socket_rate(CONNS, slice);
		if (one[r] <= 0 || many[r] <= 0)
			return -1;
	}
	double lib_p50 = bench_percentile(lib_lat, nl, 50);
	double sock_p50 = bench_percentile(sock_lat, ns, 50);
	double one_med = median(one), many_med = median(many);

	bench_print_figure(
		&(bench_figure){ .name = "cogw-ascii r 1018h:04 u32, one connection, p50",
				 .value = sock_p50,
				 .unit = "us",
				 .base_name = "the same read through libcogw, p50",
				 .base_value = lib_p50,
				 .base_unit = "us",
				 .ratio = sock_p50 / lib_p50,
				 .target = "ratio <= 1.30",
				 .verdict = bench_verdict(sock_p50 <= 1.3 * lib_p50) });
	bench_print_figure(&(bench_figure){ .name = "cogw-ascii 16 connections aggregate",
					    .value = many_med,
					    .unit = "reads/s",
					    .base_name = "one connection",
					    .base_value = one_med,
					    .base_unit = "reads/s",
					    .ratio = many_med / one_med,
					    .target = "ratio >= 4.00",
					    .verdict = bench_verdict(many_med >= 4.0 * one_med) });
	bench_note(
		"%d rounds of %.2f s each (libcogw reads, the same reads through one cogw-ascii "
		"connection, 1 and 16 connections at once); reads: %zu through libcogw (p90 %.0f "
		"us), %zu through cogw-ascii (p90 %.0f us); 16 connections / 1 per round: "
		"%.0f/%.0f %.0f/%.0f %.0f/%.0f %.0f/%.0f %.0f/%.0f reads/s",
		ROUNDS, slice, nl, bench_percentile(lib_lat, nl, 90), ns,
		bench_percentile(sock_lat, ns, 90), many[0], one[0], many[1], one[1], many[2],
		one[2], many[3], one[3], many[4], one[4]);
	return 0;
}

/* ---- against the reference gateway (by hand) ---------------------------------------- */

/* Reads/s through one kept connection, one at a time, for seconds; -1 when
 * an answer is wrong or missing. */
static double kept_rate(const char *path, const char *cmd, const char *want, double seconds)
{
	size_t n = 0;
	double t0 = bench_now_s();

	if (socket_reads(path, cmd, want, seconds, sock_lat, LAT_MAX, &n) < 0)
		return -1;
	return (double)n / (bench_now_s() - t0);
}

#define BURST 200

static void reference_report(const char *canopend, const double ours_rate[ROUNDS],
			     const double ref_rate[ROUNDS], const double ours_burst[ROUNDS],
			     const double ref_burst[ROUNDS])
{
	double a = median(ours_rate), b = median(ref_rate);
	double c = median(ours_burst), d = median(ref_burst);

	bench_note("against canopend (%s), medians of %d rounds: one kept connection, one read "
		   "at a time: cogw-ascii %.0f reads/s, canopend %.0f reads/s (%.2fx); %d reads "
		   "written at once: cogw-ascii %.0f reads/s, canopend %.0f reads/s (%.2fx)",
		   canopend, ROUNDS, a, b, a / b, BURST, c, d, c / d);
	for (int k = 0; k < ROUNDS; k++)
		bench_note("against canopend, round %d (%s first): one at a time %.0f vs %.0f "
			   "reads/s, %d at once %.0f vs %.0f reads/s",
			   k + 1, k % 2 ? "canopend" : "cogw-ascii", ours_rate[k], ref_rate[k],
			   BURST, ours_burst[k], ref_burst[k]);
}

/* COGW_BENCH_CANOPEND=path of CANopenNode's canopend, built by hand (not
 * part of this project; docs/ascii.md "Against the reference gateway"):
 * it runs as node 4 on vcan0 beside cogwd, and both gateways are asked the
 * same read of node 5 (1018h:04) over their UNIX sockets, in turns: one
 * kept connection reading one at a time (the next command after the
 * answer, as cocomm does), and BURST reads written at once. Notes, never
 * figures: make bench has no canopend. */
static void reference_notes(const char *canopend)
{
	static const char cmd[] = "[1] 1 5 r 0x1018 4 u32\n", want[] = "[1] 4242\r\n";
	char co_sock[128], co_arg[140], co_store[128], co_log[128];
	double ours_rate[ROUNDS], ref_rate[ROUNDS], ours_burst[ROUNDS], ref_burst[ROUNDS];
	double slice = run_seconds / ROUNDS;
	pid_t co;

	snprintf(co_sock, sizeof co_sock, "%s/canopend.sock", tmpdir);
	snprintf(co_arg, sizeof co_arg, "local-%s", co_sock);
	snprintf(co_store, sizeof co_store, "%s/canopend_", tmpdir);
	snprintf(co_log, sizeof co_log, "%s/canopend.log", tmpdir);
	const char *argv[] = { canopend, "vcan0", "-i", "4", "-c", co_arg, "-s", co_store, NULL };

	co = proc_spawn(argv, co_log, NULL);
	for (int i = 0; i < 100 && access(co_sock, F_OK) != 0; i++)
		sleep_ms(100);
	for (int r = 0; r < ROUNDS; r++) {
		/* in turns first, so that a trend of the host's load favours neither */
		const char *first = r % 2 ? co_sock : sock_path,
			   *second = r % 2 ? sock_path : co_sock;
		double *rate1 = r % 2 ? ref_rate : ours_rate, *rate2 = r % 2 ? ours_rate : ref_rate;
		double *burst1 = r % 2 ? ref_burst : ours_burst,
		       *burst2 = r % 2 ? ours_burst : ref_burst;

		if ((rate1[r] = kept_rate(first, cmd, want, slice)) <= 0 ||
		    (rate2[r] = kept_rate(second, cmd, want, slice)) <= 0 ||
		    (burst1[r] = burst_rate(first, cmd, want, BURST)) <= 0 ||
		    (burst2[r] = burst_rate(second, cmd, want, BURST)) <= 0)
			break;
		if (r == ROUNDS - 1) {
			reference_report(canopend, ours_rate, ref_rate, ours_burst, ref_burst);
			proc_stop(co, 15, 5000);
			return;
		}
	}
	bench_note("against canopend (%s): no answer, see its log", canopend);
	proc_dump_log(co_log, 10);
	proc_stop(co, 15, 5000);
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
	if (ascii_figures(h) < 0)
		goto out;
	const char *canopend = getenv("COGW_BENCH_CANOPEND");

	if (canopend && *canopend)
		reference_notes(canopend);

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
