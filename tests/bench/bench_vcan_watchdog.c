/* SPDX-License-Identifier: MIT */
/*
 * Benchmark: the application watchdog's reaction delay (docs/application.md).
 *
 * cogwd runs line bench0 on vcan0 (node 127, a manager, TPDO 1 mapping the
 * safe output 2000h). A client of this program declares itself essential
 * (20 ms, reactions EMCY + safe outputs), sends one keep-alive and falls
 * silent; the line misses the deadline and reacts. Measured per round: from
 * the deadline (CLOCK_MONOTONIC, carried by the APP_WD_TIMEOUT event) to the
 * EMCY 6200h frame on vcan0 as a raw reader receives it (the kernel's time
 * of reception, SO_TIMESTAMP, moved onto CLOCK_MONOTONIC); p50 and p99 over
 * the rounds. Declaring again acknowledges the trip before the next round.
 *
 * Baseline, in the same run: a bare process that arms a timerfd at an
 * absolute CLOCK_MONOTONIC deadline and writes one CAN frame when it
 * expires, received by the same kind of reader: the floor of "wake up at a
 * deadline and put a frame on the bus" without any daemon.
 *
 * Needs vcan0 and build/rel/bin/cogwd: run through tests/bench/run-vcan.
 * COGW_BENCH_WATCHDOG_ROUNDS sets the rounds (default 300).
 */
#include <errno.h>
#include <linux/can.h>
#include <linux/sockios.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/timerfd.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "tests/bench/support/bench.h"

#define OWN 127
#define EMCY_COB (0x80 + OWN)
#define BASE_COB 0x555
#define INTERVAL_MS 20
#define ROUNDS_MAX 5000

static char instance[32];
static char tmpdir[128];

static int write_config(const char *path)
{
	char t[2048];
	snprintf(t, sizeof t,
		 "{\"version\": 1, \"state_dir\": \"%s/state\", \"mailbox\": {\"instance\": "
		 "\"%s\"},\n"
		 " \"lines\": [{\"name\": \"bench0\", \"interface\": \"vcan0\", \"bitrate\": "
		 "1000000,"
		 " \"node_id\": %d, \"heartbeat_ms\": 0, \"tpdos\": 1, \"manager\": {}, \"nodes\": "
		 "[],\n"
		 "  \"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED16\", \"access\": "
		 "\"rwr\","
		 " \"default\": 500}],\n"
		 "  \"values\": [{\"index\": \"0x1800\", \"sub\": 1, \"value\": 511},"
		 " {\"index\": \"0x1800\", \"sub\": 2, \"value\": 254},"
		 " {\"index\": \"0x1A00\", \"sub\": 0, \"value\": 1},"
		 " {\"index\": \"0x1A00\", \"sub\": 1, \"value\": 536870928}],\n"
		 "  \"app\": {\"safe_outputs\": [{\"index\": \"0x2000\", \"value\": "
		 "0}]}}]}\n",
		 tmpdir, instance, OWN);
	return bench_write_file(path, t);
}

static uint64_t clock_us(clockid_t id)
{
	struct timespec ts;
	clock_gettime(id, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* A reader of vcan0 with every frame stamped at its reception. */
static int reader_open(void)
{
	int fd = can_open_raw("vcan0"), on = 1;
	if (fd >= 0 && setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on) < 0) {
		close(fd);
		return -errno;
	}
	return fd;
}

/* The next frame with this id and first two bytes: its reception time on
 * CLOCK_MONOTONIC, 0 if none came within timeout_ms. */
static uint64_t frame_time(int fd, uint32_t id, uint8_t b0, uint8_t b1, int timeout_ms)
{
	uint64_t until = bench_now_ns() / 1000000u + (uint64_t)timeout_ms;
	int64_t offset = (int64_t)clock_us(CLOCK_REALTIME) - (int64_t)clock_us(CLOCK_MONOTONIC);
	while (bench_now_ns() / 1000000u < until) {
		struct pollfd p = { .fd = fd, .events = POLLIN };
		struct can_frame f;
		struct timeval tv;
		if (poll(&p, 1, 10) <= 0 || read(fd, &f, sizeof f) != (ssize_t)sizeof f)
			continue;
		if (f.can_id != id || f.data[0] != b0 || f.data[1] != b1)
			continue;
		if (ioctl(fd, SIOCGSTAMP, &tv) < 0)
			return clock_us(CLOCK_MONOTONIC);
		return (uint64_t)((int64_t)tv.tv_sec * 1000000 + tv.tv_usec - offset);
	}
	return 0;
}

static void drain(int fd)
{
	struct can_frame f;
	struct pollfd p = { .fd = fd, .events = POLLIN };
	while (poll(&p, 1, 0) > 0 && read(fd, &f, sizeof f) > 0)
		;
}

/* ---- the watchdog ------------------------------------------------------------- */

/* The next APP_WD_TIMEOUT event. */
static int wait_trip(cogw *h, mbx_ev_appwd *ev, int timeout_ms)
{
	uint64_t until = bench_now_ns() / 1000000u + (uint64_t)timeout_ms;
	cogw_msg m;
	while (bench_now_ns() / 1000000u < until) {
		if (cogw_recv(h, &m, 50) != 0)
			continue;
		bool hit = m.code == MBX_EV_APP_WD_TIMEOUT && m.len == sizeof *ev;
		if (hit)
			memcpy(ev, m.data, sizeof *ev);
		cogw_msg_release(&m);
		if (hit)
			return 0;
	}
	return -ETIMEDOUT;
}

/* One round: declare (acknowledging the last trip), one keep-alive, the
 * trip. Delay from the deadline to the EMCY on the bus in *bus_us, the
 * line's own lateness in *line_us. */
static int watchdog_round(cogw *h, int fd, double *bus_us, double *line_us)
{
	mbx_ev_appwd ev;
	if (cogw_app_watchdog(h, 0, INTERVAL_MS, MBX_APPWD_R_EMCY | MBX_APPWD_R_SAFE_OUTPUTS, NULL,
			      3000) < 0)
		return -1;
	drain(fd);
	if (cogw_app_keepalive(h, 0, 3000) < 0 || wait_trip(h, &ev, 3000) < 0)
		return -1;
	uint64_t t = frame_time(fd, EMCY_COB, 0x00, 0x62, 1000);
	if (!t)
		return -1;
	*bus_us = (double)((int64_t)t - (int64_t)ev.deadline_us);
	*line_us = ev.late_us;
	return 0;
}

/* ---- the baseline: a timerfd and a CAN write ------------------------------------- */

/* The child: waits for each deadline the parent writes into the pipe,
 * then sends BASE_COB [round]. */
static void timer_sender(int rd)
{
	int fd = can_open_raw("vcan0");
	int tfd = timerfd_create(CLOCK_MONOTONIC, 0);
	uint64_t at;
	if (fd < 0 || tfd < 0)
		_exit(1);
	for (uint8_t round = 0; read(rd, &at, sizeof at) == (ssize_t)sizeof at; round++) {
		struct itimerspec its = { .it_value = { .tv_sec = (time_t)(at / 1000000u),
							.tv_nsec = (long)(at % 1000000u) * 1000 } };
		uint64_t ticks;
		timerfd_settime(tfd, TFD_TIMER_ABSTIME, &its, NULL);
		if (read(tfd, &ticks, sizeof ticks) != (ssize_t)sizeof ticks)
			_exit(2);
		uint8_t d[2] = { 0xBA, round };
		can_send_std(fd, BASE_COB, d, 2);
	}
	_exit(0);
}

static int baseline(double *delay, int rounds)
{
	int p[2];
	if (pipe(p) < 0)
		return -1;
	pid_t pid = fork();
	if (pid == 0) {
		close(p[1]);
		timer_sender(p[0]);
	}
	close(p[0]);
	int fd = reader_open(), n = 0;
	for (int i = 0; fd >= 0 && i < rounds; i++) {
		uint64_t at = clock_us(CLOCK_MONOTONIC) + INTERVAL_MS * 1000u;
		if (write(p[1], &at, sizeof at) != (ssize_t)sizeof at)
			break;
		uint64_t t = frame_time(fd, BASE_COB, 0xBA, (uint8_t)i, 1000);
		if (t)
			delay[n++] = (double)((int64_t)t - (int64_t)at);
	}
	close(p[1]);
	if (fd >= 0)
		close(fd);
	waitpid(pid, NULL, 0);
	return n;
}

static void print_pair(const char *pct, double value, double base)
{
	char name[160], bname[96];
	snprintf(name, sizeof name,
		 "application watchdog reaction: missed deadline -> EMCY 6200h on vcan0, %s", pct);
	snprintf(bname, sizeof bname, "a bare process's timerfd expiry -> CAN frame, %s", pct);
	bench_print_figure(
		&(bench_figure){ .name = name,
				 .value = value,
				 .unit = "us",
				 .base_name = bname,
				 .base_value = base,
				 .base_unit = "us",
				 .ratio = base > 0 ? value / base : -1,
				 .target = "none (the reaction comes within the interval "
					   "and one line wake-up)",
				 .verdict = "-" });
}

static int run(int rounds)
{
	static double bus[ROUNDS_MAX], line[ROUNDS_MAX], base[ROUNDS_MAX];
	cogw *h = NULL;
	int fd = reader_open(), n = 0, failed = 0;
	if (fd < 0 || cogw_open(&h, instance) < 0 ||
	    cogw_subscribe(h, 0, MBX_EVC_APP, NULL, 0, 3000) < 0) {
		printf("bench: cannot open the client or the reader\n");
		return -1;
	}
	for (int i = 0; i < rounds; i++) {
		if (watchdog_round(h, fd, &bus[n], &line[n]) == 0)
			n++;
		else
			failed++;
	}
	(void)cogw_app_watchdog(h, 0, 0, 0, NULL, 3000);
	cogw_close(h);
	close(fd);
	int nb = baseline(base, rounds);
	if (n < 10 || nb < 10) {
		printf("bench: too few rounds measured (%d watchdog, %d baseline)\n", n, nb);
		return -1;
	}
	double line_p50 = bench_percentile(line, (size_t)n, 50),
	       line_p99 = bench_percentile(line, (size_t)n, 99);
	double bus_p50 = bench_percentile(bus, (size_t)n, 50),
	       bus_p99 = bench_percentile(bus, (size_t)n, 99);
	double base_p50 = bench_percentile(base, (size_t)nb, 50),
	       base_p99 = bench_percentile(base, (size_t)nb, 99);
	print_pair("p50", bus_p50, base_p50);
	print_pair("p99", bus_p99, base_p99);
	bench_note("%d rounds of a %d ms watchdog (EMCY + safe outputs; %d failed), %d baseline "
		   "rounds; the line ran the reactions %.0f us (p50) / %.0f us (p99) after the "
		   "deadline by its own clock (late_us of the event); worst on the bus %.0f us",
		   n, INTERVAL_MS, failed, nb, line_p50, line_p99,
		   bench_percentile(bus, (size_t)n, 100));
	return 0;
}

int main(void)
{
	char cfg[256], log[256];
	bench_daemon d = { .pid = -1 };
	const char *r = getenv("COGW_BENCH_WATCHDOG_ROUNDS");
	int rounds = r ? atoi(r) : 300, rc = 1;
	if (rounds < 10 || rounds > ROUNDS_MAX)
		rounds = 300;
	if (bench_setup(instance, sizeof instance, "bwd", tmpdir, sizeof tmpdir, "watchdog") < 0)
		return 1;
	snprintf(cfg, sizeof cfg, "%s/cogw.json", tmpdir);
	snprintf(log, sizeof log, "%s/cogwd.log", tmpdir);
	if (write_config(cfg) == 0 && bench_daemon_start(&d, cfg, instance, log) == 0) {
		sleep_ms(500); /* the manager starts its own node (the safe-output TPDO runs) */
		rc = run(rounds) == 0 ? 0 : 1;
	}
	bench_daemon_stop(&d);
	bench_tmpdir_remove(tmpdir);
	return rc;
}
