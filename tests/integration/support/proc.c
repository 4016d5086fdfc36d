/* SPDX-License-Identifier: MIT */
#include "tests/integration/support/proc.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <net/if.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

uint64_t mono_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

void sleep_ms(unsigned ms)
{
	struct timespec ts = { .tv_sec = ms / 1000u, .tv_nsec = (long)(ms % 1000u) * 1000000L };
	while (nanosleep(&ts, &ts) == -1 && errno == EINTR)
		;
}

pid_t proc_spawn(const char *const argv[], const char *log_path, const char *const env[])
{
	fflush(stdout);
	pid_t pid = fork();
	if (pid != 0)
		return pid;
	if (log_path) {
		int fd = open(log_path, O_WRONLY | O_CREAT | O_APPEND, 0644);
		if (fd >= 0) {
			dup2(fd, STDOUT_FILENO);
			dup2(fd, STDERR_FILENO);
			close(fd);
		}
	}
	for (size_t i = 0; env && env[i]; i++)
		putenv((char *)env[i]);
	/* systemd's watchdog contract: WATCHDOG_PID names the service's pid */
	if (getenv("WATCHDOG_USEC")) {
		char pidbuf[32];
		snprintf(pidbuf, sizeof pidbuf, "%d", (int)getpid());
		setenv("WATCHDOG_PID", pidbuf, 1);
	}
	execv(argv[0], (char *const *)argv);
	fprintf(stderr, "exec %s: %s\n", argv[0], strerror(errno));
	_exit(127);
}

bool proc_exited(pid_t pid, int *status)
{
	return waitpid(pid, status, WNOHANG) == pid;
}

int proc_stop(pid_t pid, int sig, int timeout_ms)
{
	int status = 0;
	if (pid <= 0)
		return -1;
	if (proc_exited(pid, &status))
		return status;
	kill(pid, sig);
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	while (mono_ms() < until) {
		if (proc_exited(pid, &status))
			return status;
		sleep_ms(10);
	}
	kill(pid, SIGKILL);
	waitpid(pid, &status, 0);
	return -1;
}

void proc_dump_log(const char *path, int lines)
{
	char cmd[512];
	snprintf(cmd, sizeof cmd, "echo '--- %s (last %d lines)'; tail -n %d '%s'", path, lines,
		 lines, path);
	fflush(stdout);
	int rc = system(cmd);
	(void)rc;
}

bool file_contains(const char *path, const char *text)
{
	FILE *f = fopen(path, "r");
	if (!f)
		return false;
	char line[4096];
	bool found = false;
	while (!found && fgets(line, sizeof line, f))
		found = strstr(line, text) != NULL;
	fclose(f);
	return found;
}

bool file_wait_contains(const char *path, const char *text, int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	do {
		if (file_contains(path, text))
			return true;
		sleep_ms(20);
	} while (mono_ms() < until);
	return false;
}

int notify_open(notify_sock *ns)
{
	memset(ns, 0, sizeof *ns);
	snprintf(ns->path, sizeof ns->path, "/tmp/cogw-notify-%d-%llu", (int)getpid(),
		 (unsigned long long)mono_ms());
	ns->fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	if (ns->fd < 0)
		return -errno;
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	snprintf(a.sun_path, sizeof a.sun_path, "%s", ns->path);
	unlink(ns->path);
	if (bind(ns->fd, (struct sockaddr *)&a, sizeof a) != 0)
		return -errno;
	snprintf(ns->env, sizeof ns->env, "NOTIFY_SOCKET=%s", ns->path);
	return 0;
}

void notify_close(notify_sock *ns)
{
	if (ns->fd > 0)
		close(ns->fd);
	unlink(ns->path);
	ns->fd = -1;
}

static bool has_line(const char *text, const char *prefix)
{
	size_t n = strlen(prefix);
	for (const char *p = text; p && *p; p = strchr(p, '\n') ? strchr(p, '\n') + 1 : NULL)
		if (strncmp(p, prefix, n) == 0)
			return true;
	return false;
}

int notify_wait(notify_sock *ns, const char *prefix, int timeout_ms, char *out, size_t len)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	char buf[4096];
	for (;;) {
		uint64_t now = mono_ms();
		if (now >= until)
			return -ETIMEDOUT;
		struct pollfd p = { .fd = ns->fd, .events = POLLIN };
		if (poll(&p, 1, (int)(until - now)) <= 0)
			continue;
		ssize_t n = recv(ns->fd, buf, sizeof buf - 1, 0);
		if (n <= 0)
			continue;
		buf[n] = '\0';
		if (has_line(buf, prefix)) {
			if (out)
				snprintf(out, len, "%s", buf);
			return 0;
		}
	}
}

int notify_count(notify_sock *ns, const char *prefix, int window_ms)
{
	int count = 0;
	uint64_t until = mono_ms() + (uint64_t)window_ms;
	char buf[4096];
	for (;;) {
		uint64_t now = mono_ms();
		if (now >= until)
			return count;
		struct pollfd p = { .fd = ns->fd, .events = POLLIN };
		if (poll(&p, 1, (int)(until - now)) <= 0)
			continue;
		ssize_t n = recv(ns->fd, buf, sizeof buf - 1, 0);
		if (n <= 0)
			continue;
		buf[n] = '\0';
		count += has_line(buf, prefix);
	}
}

void notify_drain(notify_sock *ns)
{
	char buf[4096];
	while (recv(ns->fd, buf, sizeof buf, MSG_DONTWAIT) > 0)
		;
}

int run_capture(const char *cmd, char *out, size_t cap)
{
	FILE *p = popen(cmd, "r");
	size_t n = 0;
	int st;

	if (cap)
		out[0] = '\0';
	if (!p)
		return -1;
	if (cap) {
		n = fread(out, 1, cap - 1, p);
		out[n] = '\0';
	}
	st = pclose(p);
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

int can_open_raw(const char *ifname)
{
	int fd = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
	if (fd < 0)
		return -errno;
	struct sockaddr_can a = { .can_family = AF_CAN,
				  .can_ifindex = (int)if_nametoindex(ifname) };
	if (!a.can_ifindex || bind(fd, (struct sockaddr *)&a, sizeof a) != 0) {
		close(fd);
		return -ENODEV;
	}
	return fd;
}

int can_send_std(int fd, uint32_t id, const uint8_t *data, uint8_t len)
{
	struct can_frame f = { .can_id = id, .len = len };
	memcpy(f.data, data, len);
	return write(fd, &f, sizeof f) == (ssize_t)sizeof f ? 0 : -errno;
}

int can_wait_id(int fd, uint32_t id, uint8_t data[8], int timeout_ms)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		uint64_t now = mono_ms();
		if (now >= until)
			return -ETIMEDOUT;
		struct pollfd p = { .fd = fd, .events = POLLIN };
		if (poll(&p, 1, (int)(until - now)) <= 0)
			continue;
		struct can_frame f;
		if (read(fd, &f, sizeof f) != (ssize_t)sizeof f)
			continue;
		if ((f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) || f.can_id != id)
			continue;
		if (data)
			memcpy(data, f.data, 8);
		return f.len;
	}
}
