/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the Python package (python/, docs/python.md) against libcogw in
 * C, in the same run, through a real cogwd on vcan0.
 *
 *   - a typed read (1018h:04 u32 of a cosim node) over a kept connection:
 *     the blocking API's node.sdo.read(0x1018, 4, "u32") in a Python
 *     process (tests/bench/bench_python.py) against cogw_sdo_read_u32 from
 *     this process; 3 rounds interleaved, the median of the rounds' p50s
 *     (target: p50 <= 1.5x);
 *   - the watched values per second a Python client (asyncio API, one loop
 *     handle) keeps up with while losing none: the TPDO of a mirrored slave
 *     (6401h:01, `pdo: "auto"`) injected on vcan0 at rising rates, each for
 *     the measurement time; the highest rate whose every value arrived (no
 *     gap in the watch's sequence numbers, no overflow), against a C client
 *     watching the same object through libcogw (cogw_recv) at the same rates.
 *
 * Needs vcan0, the release cogwd and cosim, libcogw.so and a python3 (the
 * pyenv's when there is one): run through tests/bench/run-vcan (make bench).
 * Prints figures; asserts nothing, but says so loudly when a value is wrong.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define SIM_NODE 5   /* cosim: 1018h:04 = 4242 */
#define SLAVE_NODE 1 /* mirrored, its TPDO injected by the benchmark */
#define OUR_NODE 127
#define ROUNDS 3

static char instance[32], tmpdir[64];
static double run_seconds = 2.0;
static const char *python;

static const double rates[] = { 50, 100, 200, 400, 800, 1600, 3200, 6400, 12800 };
#define N_RATES (sizeof rates / sizeof rates[0])

static int write_config(const char *path, const char *eds)
{
	char text[1024];

	snprintf(text, sizeof text,
		 "{\"version\": 1, \"state_dir\": \"%s/state\","
		 " \"mailbox\": {\"instance\": \"%s\"},"
		 " \"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": %d,"
		 " \"rpdos\": 4, \"pdo\": \"auto\", \"nodes\": [{\"id\": %d, \"eds\": \"%s\"}]}]}",
		 tmpdir, instance, OUR_NODE, SLAVE_NODE, eds);
	return bench_write_file(path, text);
}

static const char *python_path(void)
{
	static char buf[512];
	char cwd[400];

	if (getcwd(cwd, sizeof cwd)) {
		snprintf(buf, sizeof buf, "%s/build/pyenv/bin/python", cwd);
		if (access(buf, X_OK) == 0)
			return buf;
	}
	return "python3";
}

/* The Python side, its output into log. */
static pid_t python_start(const char *what, const char *node, const char *arg, const char *log)
{
	static char pp[512], lib[512];
	char cwd[400];
	const char *argv[] = { python, "tests/bench/bench_python.py", what, instance, node, arg,
			       NULL };

	if (!getcwd(cwd, sizeof cwd))
		return -1;
	snprintf(pp, sizeof pp, "PYTHONPATH=%s/python/src", cwd);
	snprintf(lib, sizeof lib, "COGW_LIBRARY=%s/build/rel/lib/libcogw.so.1", cwd);
	const char *env[] = { pp, lib, "PYTHONDONTWRITEBYTECODE=1", NULL };

	return proc_spawn(argv, log, env);
}

static int python_wait(pid_t p, double timeout_s)
{
	int st = 0;

	for (double until = bench_now_s() + timeout_s; bench_now_s() < until; sleep_ms(20))
		if (proc_exited(p, &st))
			return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
	proc_stop(p, 9, 1000);
	return -1;
}

/* ---- a typed read ------------------------------------------------------------------ */

static double c_read_p50(cogw *h, int n)
{
	double *t = calloc((size_t)n, sizeof *t);
	double p50 = -1;

	for (int i = 0; t && i < n; i++) {
		uint32_t v = 0, abort = 0;
		uint64_t t0 = bench_now_ns();

		if (cogw_sdo_read_u32(h, 0, SIM_NODE, 0x1018, 4, &v, 5000, &abort) < 0 ||
		    v != 4242) {
			printf("bench_vcan_python: libcogw read failed (abort %08X)\n", abort);
			free(t);
			return -1;
		}
		t[i] = (double)(bench_now_ns() - t0) / 1000.0;
	}
	if (t)
		p50 = bench_percentile(t, (size_t)n, 50);
	free(t);
	return p50;
}

static double python_read_p50(int n)
{
	char log[256], count[16], *text = NULL, *p;
	size_t cap = 0;
	double *t = calloc((size_t)n, sizeof *t), p50 = -1;
	int k = 0;
	FILE *f;

	snprintf(log, sizeof log, "%s/python-read.log", tmpdir);
	snprintf(count, sizeof count, "%d", n);
	unlink(log); /* each round's own figures */
	pid_t pid = python_start("read", "5", count, log);

	if (!t || pid < 0 || python_wait(pid, 60 + n * 0.05) < 0 || !(f = fopen(log, "r"))) {
		printf("bench_vcan_python: the Python reader failed\n");
		proc_dump_log(log, 20);
		free(t);
		return -1;
	}
	while (getline(&text, &cap, f) > 0)
		if (strncmp(text, "python read us: ", 16) == 0)
			for (p = strtok(text + 16, " \n"); p && k < n; p = strtok(NULL, " \n"))
				t[k++] = atof(p);
	fclose(f);
	free(text);
	if (k == n)
		p50 = bench_percentile(t, (size_t)n, 50);
	free(t);
	return p50;
}

static int read_figures(cogw *h)
{
	int n = (int)(300 * run_seconds);
	double c[ROUNDS], py[ROUNDS];
	char rounds[256];
	size_t len = 0;

	for (int r = 0; r < ROUNDS; r++) {
		c[r] = c_read_p50(h, n);
		py[r] = python_read_p50(n);
		if (c[r] <= 0 || py[r] <= 0)
			return -1;
		len += (size_t)snprintf(rounds + len, sizeof rounds - len, "%s%.0f/%.0f",
					r ? ", " : "", py[r], c[r]);
	}
	double cm = bench_percentile(c, ROUNDS, 50), pm = bench_percentile(py, ROUNDS, 50);

	bench_print_figure(&(bench_figure){
		.name = "Python typed read 1018h:04 u32 over a kept connection, p50",
		.value = pm,
		.unit = "us",
		.base_name = "the same read through libcogw in C (cogw_sdo_read_u32), p50",
		.base_value = cm,
		.base_unit = "us",
		.ratio = pm / cm,
		.target = "ratio <= 1.50",
		.verdict = bench_verdict(pm / cm <= 1.5) });
	bench_note("typed read: %d reads per round and side, %d rounds interleaved, medians of the "
		   "rounds' p50 (Python/C us per round: %s)",
		   n, ROUNDS, rounds);
	return 0;
}

/* ---- watched values ------------------------------------------------------------------ */

/* Sends the slave's TPDO at `rate` for run_seconds in this child process,
 * the value counting up from 1; exits with nothing to say. */
static void inject(double rate)
{
	int fd = can_open_raw("vcan0");
	uint64_t t0 = bench_now_ns(), step = (uint64_t)(1e9 / rate);
	uint64_t n = (uint64_t)(rate * run_seconds);

	if (fd < 0)
		_exit(1);
	for (uint64_t k = 1; k <= n; k++) {
		uint64_t at = t0 + k * step, now = bench_now_ns();
		uint8_t d[8] = { (uint8_t)k, (uint8_t)(k >> 8) };

		if (at > now) {
			struct timespec ts = { (time_t)((at - now) / 1000000000u),
					       (long)((at - now) % 1000000000u) };
			nanosleep(&ts, NULL);
		}
		while (can_send_std(fd, 0x180 + SLAVE_NODE, d, 8) < 0 && errno == ENOBUFS)
			sleep_ms(1);
	}
	_exit(0);
}

static pid_t injector_start(double rate)
{
	fflush(stdout);
	pid_t p = fork();

	if (p == 0)
		inject(rate);
	return p;
}

/* The C client: every value of one run at `rate`; 0 when none was lost. */
static int c_watch_run(cogw *h, double rate, long *received, long *lost_out)
{
	long lost = 0, got = 0;
	uint32_t last_seq = 0;
	pid_t inj = injector_start(rate);
	bool injecting = true;

	for (double quiet_until = 0;;) {
		cogw_msg m;
		int st;

		if (injecting && proc_exited(inj, &st)) {
			injecting = false;
			quiet_until = bench_now_s() + 1.0;
		}
		if (!injecting && bench_now_s() > quiet_until)
			break;
		if (cogw_recv(h, &m, 50) < 0)
			continue;
		mbx_dev_value v;
		const uint8_t *data;

		lost += m.dropped;
		if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_DEV_VALUE &&
		    cogw_dev_value_parse(m.data, m.len, &v, &data) == 0) {
			if (got && v.seq != last_seq + 1)
				lost += v.seq > last_seq ? v.seq - last_seq - 1 : 0;
			last_seq = v.seq;
			got++;
		}
		cogw_msg_release(&m);
	}
	*received = got;
	*lost_out = lost;
	return lost == 0 && got == (long)(rate * run_seconds) ? 0 : -1;
}

static int python_watch_run(double rate, long *received, long *lost_out)
{
	char log[256], secs[16], *text = NULL;
	size_t cap = 0;
	long got = -1, lost = -1;
	FILE *f;

	snprintf(log, sizeof log, "%s/python-watch.log", tmpdir);
	snprintf(secs, sizeof secs, "%.1f", run_seconds + 3.0);
	unlink(log);
	pid_t py = python_start("watch", "1", secs, log);

	if (py < 0 || !file_wait_contains(log, "ready", 60000)) {
		proc_dump_log(log, 20);
		return -2;
	}
	pid_t inj = injector_start(rate);

	waitpid(inj, NULL, 0);
	if (python_wait(py, run_seconds + 30) < 0 || !(f = fopen(log, "r"))) {
		proc_dump_log(log, 20);
		return -2;
	}
	while (getline(&text, &cap, f) > 0)
		sscanf(text, "python watch: received %ld lost %ld", &got, &lost);
	fclose(f);
	free(text);
	*received = got;
	*lost_out = lost;
	return lost == 0 && got == (long)(rate * run_seconds) ? 0 : -1;
}

/* The highest rate of rates[] one client kept up with; its trace in `trace`. */
static double kept_up(cogw *h, char *trace, size_t cap)
{
	double best = 0;
	size_t len = 0;

	trace[0] = '\0';
	for (size_t i = 0; i < N_RATES; i++) {
		long got = 0, lost = 0;
		int rc = h ? c_watch_run(h, rates[i], &got, &lost)
			   : python_watch_run(rates[i], &got, &lost);

		if (rc == -2)
			return -1;
		len += (size_t)snprintf(trace + len, cap - len, "%s%.0f/s: %ld of %.0f (%ld lost)",
					i ? ", " : "", rates[i], got, rates[i] * run_seconds, lost);
		if (rc < 0)
			break;
		best = rates[i];
	}
	return best;
}

static int watch_figures(cogw *h)
{
	mbx_dev_obj_req o = { .node = SLAVE_NODE, .index = 0x6401, .sub = 1 };
	mbx_dev_watch_resp r;
	uint32_t abort = 0;
	char ctrace[1024], ptrace[1024];

	if (cogw_dev_watch(h, 0, &o, 0, &r, 5000, &abort) < 0) {
		printf("bench_vcan_python: watch refused (abort %08X)\n", abort);
		return -1;
	}
	double c = kept_up(h, ctrace, sizeof ctrace);

	cogw_dev_unwatch(h, 0, &o, 5000);
	double py = kept_up(NULL, ptrace, sizeof ptrace);

	if (c < 0 || py < 0)
		return -1;
	bench_print_figure(&(bench_figure){
		.name = "watched values/s a Python client (asyncio) keeps up with, losing none",
		.value = py,
		.unit = "values/s",
		.base_name = "a C client through libcogw (cogw_recv)",
		.base_value = c,
		.base_unit = "values/s",
		.ratio = c > 0 ? py / c : -1,
		.target = "none (context)",
		.verdict = "-" });
	bench_note("watch: a TPDO of node %d (6401h:01) injected on vcan0 for %.1f s per rate, "
		   "the rates doubled until a value was lost or late; received of sent per rate: "
		   "Python %s; C %s",
		   SLAVE_NODE, run_seconds, ptrace, ctrace);
	return 0;
}

/* ---- set-up ------------------------------------------------------------------------ */

static int device_answers(cogw *h)
{
	for (uint64_t until = mono_ms() + 15000; mono_ms() < until; sleep_ms(100)) {
		uint32_t v = 0, abort = 0;

		if (cogw_sdo_read_u32(h, 0, SIM_NODE, 0x1018, 4, &v, 3000, &abort) == 0)
			return 0;
	}
	printf("bench_vcan_python: cosim node %d does not answer\n", SIM_NODE);
	return -1;
}

int main(void)
{
	const char *secs = getenv("COGW_BENCH_SECONDS");
	char cfg[256], log[256], simlog[256], eds[256], prog[256];
	bench_daemon d = { .pid = -1 };
	pid_t sim = -1;
	cogw *h = NULL;
	int status = 1;

	if (secs && atof(secs) > 0)
		run_seconds = atof(secs);
	python = python_path();
	if (bench_setup(instance, sizeof instance, "bench", tmpdir, sizeof tmpdir, "python") < 0)
		return 1;
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	snprintf(simlog, sizeof simlog, "%s/cosim.log", tmpdir);
	snprintf(eds, sizeof eds, "%s/slave.eds", tmpdir);
	printf("bench_vcan_python: cogwd + cosim on vcan0, %s, %.1f s per measurement\n", python,
	       run_seconds);
	const char *sim_argv[] = {
		bench_program("cosim", prog, sizeof prog),     "--interface", "vcan0", "--device",
		"tests/integration/config/ascii-types.json:5", "--quiet",     NULL
	};

	if (bench_write_tpdo_eds(eds, 1) < 0 || write_config(cfg, eds) < 0)
		goto out;
	sim = proc_spawn(sim_argv, simlog, NULL);
	if (bench_daemon_start(&d, cfg, instance, log) < 0 || cogw_open(&h, instance) < 0 ||
	    device_answers(h) < 0 || bench_go_operational(h, OUR_NODE) < 0)
		goto out;
	fflush(stdout);
	if (read_figures(h) < 0 || watch_figures(h) < 0)
		goto out;
	status = 0;
out:
	cogw_close(h);
	if (status)
		printf("bench_vcan_python: FAILED, daemon log %s\n", log);
	bench_daemon_stop(&d);
	if (sim > 0)
		proc_stop(sim, 15, 5000);
	if (!status)
		bench_tmpdir_remove(tmpdir);
	return status;
}
