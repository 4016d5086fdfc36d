/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/support/proc.h - real processes, real sockets for the
 * integration tests: spawn the daemon / simulator / clients, observe
 * sd_notify datagrams on a real NOTIFY_SOCKET, watch a vcan line.
 */
#ifndef COGW_TESTS_PROC_H
#define COGW_TESTS_PROC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

/* Start argv[0] with argv; stdout+stderr appended to log_path (NULL =
 * inherit). env: extra "NAME=value" strings, NULL-terminated, or NULL. */
pid_t proc_spawn(const char *const argv[], const char *log_path, const char *const env[]);
/* Send sig, wait up to timeout_ms, then SIGKILL. Returns the wait status
 * (as waitpid), or -1. */
int proc_stop(pid_t pid, int sig, int timeout_ms);
/* Non-blocking: has it exited? Fills *status. */
bool proc_exited(pid_t pid, int *status);
/* Print the last lines of a log file to stdout (for failure diagnosis). */
void proc_dump_log(const char *path, int lines);
/* True if the file contains the text. */
bool file_contains(const char *path, const char *text);
/* Wait until the file contains the text. */
bool file_wait_contains(const char *path, const char *text, int timeout_ms);

/* A NOTIFY_SOCKET: an AF_UNIX datagram socket bound at a path in /tmp. */
typedef struct notify_sock {
	int fd;
	char path[108];
	char env[128]; /* "NOTIFY_SOCKET=/tmp/..." */
} notify_sock;
int notify_open(notify_sock *ns);
void notify_close(notify_sock *ns);
/* Wait for a datagram with a line starting with `prefix` (e.g. "READY=1").
 * The matching datagram's text goes to out. Returns 0 or -ETIMEDOUT. */
int notify_wait(notify_sock *ns, const char *prefix, int timeout_ms, char *out, size_t len);
/* Count datagrams containing `prefix` within window_ms. */
int notify_count(notify_sock *ns, const char *prefix, int window_ms);
/* Throw away the datagrams that came so far. */
void notify_drain(notify_sock *ns);

/* Run a shell command (e.g. build/san/bin/cogwctl ...), its stdout into out
 * (cap bytes with the NUL). Its exit status, -1 if it did not exit. */
int run_capture(const char *cmd, char *out, size_t cap);

/* Raw CAN on a vcan line. */
int can_open_raw(const char *ifname);
int can_send_std(int fd, uint32_t id, const uint8_t *data, uint8_t len);
/* Wait for a frame with this 11-bit id; returns its length or -ETIMEDOUT. */
int can_wait_id(int fd, uint32_t id, uint8_t data[8], int timeout_ms);

uint64_t mono_ms(void);
void sleep_ms(unsigned ms);

#endif /* COGW_TESTS_PROC_H */
