/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/support/daemon.h - start and stop the real cogwd and
 * cosim processes for the daemon integration tests (test_daemon_clients.c,
 * test_daemon_system.c), and check that nothing is left behind.
 *
 * All files live in one temporary directory below /tmp (the only writable
 * place inside the vcan VM). Typical use:
 *
 *     static daemon_run d;
 *     static cosim_run sim0;
 *     void setUp(void) {
 *         TEST_ASSERT_EQUAL_INT(0, daemon_start(&d, &(daemon_opts){
 *             .config_json = MY_JSON, .instance = "t1", .n_lines = 3,
 *             .notify = true }));
 *         const char *dev[] = { "etc/devices/sti-pressure.json", NULL };
 *         TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, d.dir, 0, dev, NULL));
 *     }
 *     void tearDown(void) {
 *         cosim_stop(&sim0, 3000);
 *         daemon_stop(&d, 10000);              // also removes d.dir
 *     }
 *
 * Every function may be called on a zeroed, half-started or already stopped
 * object (stop is idempotent), so tearDown can call them unconditionally.
 * Paths of binaries are relative to the repository root (the tests run from
 * there, in the VM too).
 */
#ifndef COGW_TESTS_DAEMON_H
#define COGW_TESTS_DAEMON_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "tests/integration/support/proc.h"

#define DAEMON_PATH_MAX 160

/* The default configuration's lines without a CiA 302-2 manager. */
#define HAND_STARTED "tests/integration/config/hand-started.json"

typedef struct daemon_opts {
	/* Configuration text written to <dir>/cogw.json and passed with
	 * --config; NULL = no --config (the embedded default, instance "main"). */
	const char *config_json;
	/* Or a configuration file passed with --config as it is, relative to
	 * the repository root (e.g. HAND_STARTED for tests that start the
	 * nodes by hand: the embedded default boots them with its manager). */
	const char *config_file;
	/* Mailbox instance the configuration names (NULL = "main"): used to
	 * find the command queues /cogw.<instance>.line<N>.cmd. */
	const char *instance;
	/* Lines whose command queues must exist before daemon_start returns
	 * (0 = 3). */
	unsigned n_lines;
	/* Give the daemon a NOTIFY_SOCKET and wait for READY=1 (else only the
	 * queues are awaited). */
	bool notify;
	/* With notify: close the socket once READY=1 came. Keep it (false)
	 * only if the test reads it regularly: an unread datagram socket fills
	 * up after ~10 messages (net.unix.max_dgram_qlen), then the daemon's
	 * sd_notify() blocks its main thread (STATUS= goes out every second)
	 * and SIGTERM/SIGHUP are no longer handled. daemon_stop() drains it. */
	bool drop_notify;
	/* With notify: WATCHDOG_USEC for the daemon (0 = none). */
	uint64_t watchdog_usec;
	/* Daemon binary (NULL = build/san/bin/cogwd). */
	const char *binary;
	/* argv prefix, e.g. {"/usr/bin/valgrind", "--leak-check=full", NULL}
	 * (NULL = run the binary directly). */
	const char *const *wrapper;
	/* Extra daemon arguments, NULL-terminated (e.g. "-v"). */
	const char *const *extra_args;
	/* Wait for READY/queues this long (0 = 20000 ms; valgrind needs more). */
	int ready_timeout_ms;
	/* --state-dir (NULL = <dir>/state): give the state_dir of an earlier
	 * run to restart on its saved parameters (test_daemon_system.c). */
	const char *state_dir;
} daemon_opts;

typedef struct daemon_run {
	pid_t pid;                         /* 0 = not running */
	char dir[64];                      /* temp dir (created by daemon_start) */
	char config_path[DAEMON_PATH_MAX]; /* "" = embedded default */
	char log_path[DAEMON_PATH_MAX];    /* daemon stdout+stderr */
	char state_dir[DAEMON_PATH_MAX];   /* --state-dir, inside dir */
	char instance[32];
	unsigned n_lines;
	bool has_notify;
	notify_sock ns;       /* valid while has_notify */
	char ready_text[512]; /* the datagram that carried READY=1 */
	int exit_status;      /* waitpid status after stop, -1 */
} daemon_run;

/* Create a temp dir, write the configuration, start the daemon with
 * --state-dir <dir>/state, wait for READY=1 (opts->notify) and for the
 * command queues of lines 0..n_lines-1. Returns 0, or a negative errno
 * (-ETIMEDOUT, -ECHILD if it exited: the log is dumped to stdout). */
int daemon_start(daemon_run *d, const daemon_opts *opts);
/* SIGTERM, wait up to timeout_ms (then SIGKILL), store the wait status in
 * d->exit_status and return it (-1 if it had to be killed). Dumps the log's
 * tail when the exit was not clean. Closes the notify socket. Does not
 * remove d->dir (daemon_cleanup does). Idempotent. */
int daemon_stop(daemon_run *d, int timeout_ms);
/* Stop (if running) and remove d->dir recursively. Idempotent. */
void daemon_cleanup(daemon_run *d);
/* The setpriv argument that gives a process exactly the capability
 * bounding set of etc/cogwd.service ("--bounding-set=-all,+sys_nice,...").
 * 0, or -ENOENT when the unit names none, or -errno. */
int daemon_unit_bounding_set(char *buf, size_t cap);
/* Write json as the daemon's configuration file, send SIGHUP and wait for
 * RELOADING=1, then READY=1 (each up to timeout_ms; the daemon started with
 * notify). 0, -ETIMEDOUT, -EINVAL (no notify socket) or -errno. */
int daemon_reload(daemon_run *d, const char *json, int timeout_ms);
/* Path of line `line`'s command queue, "/cogw.<instance>.line<N>.cmd". */
void daemon_cmd_queue(const daemon_run *d, unsigned line, char *buf, size_t cap);

/* Write text to path (creating/truncating it). 0 or -errno. */
int write_text_file(const char *path, const char *text);

/* One cosim process on one vcan line. */
typedef struct cosim_run {
	pid_t pid;          /* 0 = not running */
	unsigned line;      /* vcan<line> */
	char ctl_path[100]; /* control socket (fits sun_path) */
	char log_path[DAEMON_PATH_MAX];
	uint8_t node_ids[8]; /* nodes whose boot-up was seen */
	unsigned n_nodes;
	int exit_status;
} cosim_run;

/* Start build/san/bin/cosim on vcan<line> with the device files in
 * devices[] (NULL-terminated; "FILE:N" overrides the node id as cosim
 * allows), control socket and log in dir, extra arguments extra[]
 * (NULL-terminated, or NULL, e.g. "--autostart"). Waits (10 s) for the
 * boot-up frame 700h+id of every node: the node id is the ":N" suffix, or
 * read from the file's "node_id" (default 1); not with "--silent" in extra
 * (the devices are off the bus until "silent off"). Returns 0 or -errno. */
int cosim_start(cosim_run *c, const char *dir, unsigned line, const char *const devices[],
		const char *const extra[]);
/* One control command; the answer ("ok ..." / "error: ...") goes to reply
 * (may be NULL). Returns 0 if the answer starts with "ok", -EIO on
 * "error", -ETIMEDOUT, or -errno. */
int cosim_ctl(cosim_run *c, const char *cmd, char *reply, size_t cap, int timeout_ms);
/* SIGTERM, wait, store and return the wait status (-1 if killed). Idempotent. */
int cosim_stop(cosim_run *c, int timeout_ms);

/* What is left of an instance: message queues /dev/mqueue/cogw.<instance>.*
 * (all of them: daemon command queues and client queues) and, if pids are
 * given, those still alive. Writes a one-line description to report
 * (may be NULL) and returns the number of leftovers (0 = clean). */
int daemon_leftovers(const char *instance, const pid_t *pids, size_t n_pids, char *report,
		     size_t cap);
/* Remove every /dev/mqueue/cogw.<instance>.* (tearDown after a failure). */
void daemon_unlink_queues(const char *instance);

#endif /* COGW_TESTS_DAEMON_H */
