/* SPDX-License-Identifier: MIT */
/*
 * tests/bench/support/bench.h - what the vcan benchmarks share: the one
 * figure line format that tests/bench/report parses, timing and statistics
 * helpers, and a cogwd started from a configuration the benchmark writes.
 *
 * Figures are printed, never asserted. Every figure stands beside a
 * baseline measured in the same run, because absolute numbers differ from
 * machine to machine (and by an order of magnitude between native and the
 * software-emulated VM).
 */
#ifndef COGW_TESTS_BENCH_H
#define COGW_TESTS_BENCH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "tests/integration/support/proc.h"

/* One figure, printed as one line that tests/bench/report parses:
 *   figure: NAME = VALUE UNIT; baseline: BNAME = BVALUE BUNIT; ratio: R; target: T; verdict: V
 * NAME, BNAME, T and V must not contain ';' or '='. ratio < 0 prints "-"
 * (no ratio makes sense), base_name NULL prints "baseline: none". */
typedef struct bench_figure {
	const char *name;
	double value;
	const char *unit;
	const char *base_name;
	double base_value;
	const char *base_unit;
	double ratio;
	const char *target;  /* "ratio <= 2.00", "none (context)" */
	const char *verdict; /* "met", "not met", "-" */
} bench_figure;
void bench_print_figure(const bench_figure *f);
const char *bench_verdict(bool met);

/* Also parsed by the report: "note: TEXT" lines go under the table. */
void bench_note(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

uint64_t bench_now_ns(void);
double bench_now_s(void);
/* Sorts v in place; p in 0..100 (nearest rank). */
double bench_percentile(double *v, size_t n, double p);
bool bench_in_vm(void);
/* /proc/sys/fs/mqueue/msg_max (10 if unreadable). */
unsigned bench_mq_msg_max(void);

/* Lift RLIMIT_MSGQUEUE as far as allowed (root: unlimited): the default
 * 800 KiB per user holds the queues of only a few clients with deep event
 * queues. Returns the new soft limit in bytes (RLIM_INFINITY as UINT64_MAX). */
uint64_t bench_raise_mq_limit(void);

/* Context switches (wake-ups) of process pid so far: voluntary and
 * involuntary, summed over its threads named thread (NULL: all of them),
 * from /proc/PID/task/TID/status. 0, or -1 when pid is gone. */
int bench_ctx_switches(pid_t pid, const char *thread, uint64_t *vol, uint64_t *invol);

/* Path of a release program: $COGW_BENCH_BIN/<name>, else build/rel/bin/<name>. */
const char *bench_program(const char *name, char *buf, size_t len);

/* A temporary directory below /tmp, removed (with its files) by
 * bench_tmpdir_remove. */
int bench_tmpdir_create(char *dir, size_t len, const char *tag);
/* What every benchmark does first: SIGPIPE ignored (a dying peer must not
 * end the run), a mailbox instance "<prefix><pid>" of its own and a
 * temporary directory tagged tag. 0, or -errno. */
int bench_setup(char *instance, size_t ilen, const char *prefix, char *dir, size_t dlen,
		const char *tag);
void bench_tmpdir_remove(const char *dir);
int bench_write_file(const char *path, const char *text);
/* The EDS of a slave with `tpdos` (1..4) event-driven TPDOs on the
 * predefined COB-IDs ($NODEID + 180h, 280h, ...): TPDO n maps
 * 6401h:(4n-3..4n), four INTEGER16. */
int bench_write_tpdo_eds(const char *path, int tpdos);

/* cogwd from a configuration file, READY=1 awaited on a real NOTIFY_SOCKET. */
typedef struct bench_daemon {
	pid_t pid;
	notify_sock ns;
	char log[256];
	char instance[32];
} bench_daemon;
/* config_path: written by the caller; instance: its mailbox.instance (for
 * the queue clean-up). Returns 0 or -1 (log dumped). */
int bench_daemon_start(bench_daemon *d, const char *config_path, const char *instance,
		       const char *log_path);
/* SIGTERM, wait, then remove any queue of the instance left behind. */
void bench_daemon_stop(bench_daemon *d);
/* Remove /dev/mqueue/cogw.<instance>.* (what a killed daemon or client
 * left behind). */
void bench_unlink_instance_queues(const char *instance);

/* Start the daemon's node `node_id` of line 0 on vcan0 (an NMT start frame
 * from the bus: its PDOs, the mirror's too, work only in OPERATIONAL) and
 * wait until line 0 says so. 0, or -1 (said on stdout). */
typedef struct cogw cogw;
int bench_go_operational(cogw *h, uint8_t node_id);

/* Cumulative on-CPU time of one thread of another process, in seconds:
 * /proc/<pid>/task/<tid>/schedstat (ns) where the kernel has it, else
 * utime+stime from .../stat (clock ticks). Negative if unreadable. */
double bench_thread_cpu_s(pid_t pid, pid_t tid);
/* Thread id of the thread of pid named `comm` (as in /proc/.../comm), or -1. */
pid_t bench_find_thread(pid_t pid, const char *comm);
/* Whole process (all threads), seconds; negative if unreadable. */
double bench_process_cpu_s(pid_t pid);

#endif /* COGW_TESTS_BENCH_H */
