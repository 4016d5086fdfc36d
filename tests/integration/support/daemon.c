/* SPDX-License-Identifier: MIT */
#include "tests/integration/support/daemon.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <mqueue.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#define DEFAULT_COGWD "build/san/bin/cogwd"
#define DEFAULT_COSIM "build/san/bin/cosim"

int write_text_file(const char *path, const char *text)
{
	FILE *f = fopen(path, "w");
	if (!f)
		return -errno;
	size_t n = strlen(text);
	int rc = fwrite(text, 1, n, f) == n ? 0 : -EIO;
	if (fclose(f) != 0 && rc == 0)
		rc = -errno;
	return rc;
}

int daemon_reload(daemon_run *d, const char *json, int timeout_ms)
{
	int rc = write_text_file(d->config_path, json);

	if (rc < 0)
		return rc;
	if (!d->has_notify)
		return -EINVAL;
	notify_drain(&d->ns);
	if (kill(d->pid, SIGHUP) != 0)
		return -errno;
	if ((rc = notify_wait(&d->ns, "RELOADING=1", timeout_ms, NULL, 0)) < 0)
		return rc;
	return notify_wait(&d->ns, "READY=1", timeout_ms, NULL, 0);
}

void daemon_cmd_queue(const daemon_run *d, unsigned line, char *buf, size_t cap)
{
	snprintf(buf, cap, "/cogw.%s.line%u.cmd", d->instance, line);
}

int daemon_unit_bounding_set(char *buf, size_t cap)
{
	FILE *f = fopen("etc/cogwd.service", "r");
	char line[512];
	int rc = -ENOENT;

	if (!f)
		return -errno;
	snprintf(buf, cap, "--bounding-set=-all");
	while (fgets(line, sizeof line, f)) {
		if (strncmp(line, "CapabilityBoundingSet=", 22) != 0)
			continue;
		rc = 0;
		for (char *tok = strtok(line + 22, " \t\n"); tok; tok = strtok(NULL, " \t\n")) {
			size_t n = strlen(buf);

			snprintf(buf + n, cap - n, ",+%s", tok + 4); /* CAP_X -> +X */
			for (char *q = buf + n; *q; q++)
				*q = (char)(*q >= 'A' && *q <= 'Z' ? *q - 'A' + 'a' : *q);
		}
	}
	fclose(f);
	return rc;
}

static bool queue_exists(const char *name)
{
	/* Opening for writing (non-blocking) consumes nothing; the daemon
	 * creates the queue only once its line is ready to serve it. */
	mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK);
	if (q == (mqd_t)-1)
		return false;
	mq_close(q);
	return true;
}

/* Is name (after "cogw.<instance>.") a client queue "c<pid>.<rand>.resp|evt"
 * of a process that is still alive? */
static bool live_client_queue(const char *rest)
{
	int pid = 0;
	return sscanf(rest, "c%d.", &pid) == 1 && pid > 0 && (kill(pid, 0) == 0 || errno != ESRCH);
}

/* Remove /dev/mqueue/cogw.<instance>.*; with keep_live_clients not the
 * queues of a client process that is still alive. */
static void unlink_queues(const char *instance, bool keep_live_clients)
{
	char prefix[64];
	snprintf(prefix, sizeof prefix, "cogw.%s.", instance);
	size_t plen = strlen(prefix);
	DIR *dir = opendir("/dev/mqueue");
	if (!dir)
		return;
	struct dirent *e;
	while ((e = readdir(dir)) != NULL) {
		if (strncmp(e->d_name, prefix, plen) != 0)
			continue;
		if (keep_live_clients && live_client_queue(e->d_name + plen))
			continue;
		char name[300];
		snprintf(name, sizeof name, "/%s", e->d_name);
		mq_unlink(name);
	}
	closedir(dir);
}

void daemon_unlink_queues(const char *instance)
{
	unlink_queues(instance, false);
}

int daemon_start(daemon_run *d, const daemon_opts *opts)
{
	memset(d, 0, sizeof *d);
	d->exit_status = -1;
	d->ns.fd = -1;
	snprintf(d->instance, sizeof d->instance, "%s", opts->instance ? opts->instance : "main");
	d->n_lines = opts->n_lines ? opts->n_lines : 3;

	snprintf(d->dir, sizeof d->dir, "/tmp/cogw-it-XXXXXX");
	if (!mkdtemp(d->dir)) {
		int e = -errno;
		d->dir[0] = '\0';
		return e;
	}
	snprintf(d->log_path, sizeof d->log_path, "%s/cogwd.log", d->dir);
	if (opts->state_dir)
		snprintf(d->state_dir, sizeof d->state_dir, "%s", opts->state_dir);
	else
		snprintf(d->state_dir, sizeof d->state_dir, "%s/state", d->dir);
	if (opts->config_json) {
		snprintf(d->config_path, sizeof d->config_path, "%s/cogw.json", d->dir);
		int rc = write_text_file(d->config_path, opts->config_json);
		if (rc < 0)
			return rc;
	} else if (opts->config_file) {
		snprintf(d->config_path, sizeof d->config_path, "%s", opts->config_file);
	}

	/* A stale command queue of an earlier failed run would make the wait
	 * below succeed before the daemon is up (and the daemon may refuse
	 * it); a dead client's queues are litter. A live client's queues
	 * stay: a client of the previous daemon carries on across a restart
	 * (test_daemon_system: a client survives a daemon kill and restart),
	 * as it does when systemd restarts cogwd; unlinked, the new daemon
	 * cannot open them to answer the client's new REGISTER. */
	unlink_queues(d->instance, true);

	const char *argv[32];
	size_t argc = 0;
	for (size_t i = 0; opts->wrapper && opts->wrapper[i] && argc < 16; i++)
		argv[argc++] = opts->wrapper[i];
	/* COGW_TEST_COGWD runs the tests against another build of cogwd
	 * (e.g. an older one, to see a regression test fail there). */
	const char *bin = getenv("COGW_TEST_COGWD");
	argv[argc++] = opts->binary ? opts->binary : bin && *bin ? bin : DEFAULT_COGWD;
	if (d->config_path[0]) {
		argv[argc++] = "--config";
		argv[argc++] = d->config_path;
	}
	argv[argc++] = "--state-dir";
	argv[argc++] = d->state_dir;
	for (size_t i = 0; opts->extra_args && opts->extra_args[i] && argc < 30; i++)
		argv[argc++] = opts->extra_args[i];
	argv[argc] = NULL;

	char wd_env[64];
	const char *env[3] = { NULL, NULL, NULL };
	if (opts->notify) {
		int rc = notify_open(&d->ns);
		if (rc < 0)
			return rc;
		d->has_notify = true;
		env[0] = d->ns.env;
		if (opts->watchdog_usec) {
			snprintf(wd_env, sizeof wd_env, "WATCHDOG_USEC=%llu",
				 (unsigned long long)opts->watchdog_usec);
			env[1] = wd_env;
		}
	}
	d->pid = proc_spawn(argv, d->log_path, env);
	if (d->pid < 0) {
		d->pid = 0;
		return -ECHILD;
	}

	int timeout_ms = opts->ready_timeout_ms > 0 ? opts->ready_timeout_ms : 20000;
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	if (opts->notify) {
		char text[512];
		/* poll READY in slices so that an early exit is noticed at once */
		int rc = -ETIMEDOUT;
		while (mono_ms() < until) {
			rc = notify_wait(&d->ns, "READY=1", 200, text, sizeof text);
			if (rc == 0) {
				snprintf(d->ready_text, sizeof d->ready_text, "%s", text);
				break;
			}
			if (proc_exited(d->pid, &d->exit_status)) {
				d->pid = 0;
				printf("cogwd exited during start-up (status 0x%x)\n",
				       d->exit_status);
				proc_dump_log(d->log_path, 40);
				return -ECHILD;
			}
		}
		if (rc != 0) {
			printf("cogwd: no READY=1 within %d ms\n", timeout_ms);
			proc_dump_log(d->log_path, 40);
			return -ETIMEDOUT;
		}
		if (opts->drop_notify) {
			/* the daemon's later sd_notify calls fail (ECONNREFUSED)
			 * instead of blocking on a full socket */
			notify_close(&d->ns);
			d->has_notify = false;
		}
	}
	for (unsigned line = 0; line < d->n_lines; line++) {
		char q[96];
		daemon_cmd_queue(d, line, q, sizeof q);
		while (!queue_exists(q)) {
			if (proc_exited(d->pid, &d->exit_status)) {
				d->pid = 0;
				printf("cogwd exited during start-up (status 0x%x)\n",
				       d->exit_status);
				proc_dump_log(d->log_path, 40);
				return -ECHILD;
			}
			if (mono_ms() >= until) {
				printf("cogwd: queue %s missing after %d ms\n", q, timeout_ms);
				proc_dump_log(d->log_path, 40);
				return -ETIMEDOUT;
			}
			sleep_ms(20);
		}
	}
	return 0;
}

/* Read whatever sits in the notify socket: a daemon blocked in sd_notify()
 * on a full socket cannot see its SIGTERM. */
static void drain_notify(daemon_run *d)
{
	char buf[4096];
	while (d->has_notify && recv(d->ns.fd, buf, sizeof buf, MSG_DONTWAIT) > 0)
		;
}

int daemon_stop(daemon_run *d, int timeout_ms)
{
	if (d->pid > 0) {
		drain_notify(d);
		kill(d->pid, SIGTERM);
		uint64_t until = mono_ms() + (uint64_t)(timeout_ms > 0 ? timeout_ms : 0);
		bool exited = false;
		while (!(exited = proc_exited(d->pid, &d->exit_status)) && mono_ms() < until) {
			drain_notify(d);
			sleep_ms(10);
		}
		if (!exited) {
			printf("cogwd: no exit within %d ms of SIGTERM: SIGKILL\n", timeout_ms);
			kill(d->pid, SIGKILL);
			waitpid(d->pid, NULL, 0);
			d->exit_status = -1;
		}
		d->pid = 0;
		bool clean = d->exit_status != -1 && WIFEXITED(d->exit_status) &&
			     WEXITSTATUS(d->exit_status) == 0;
		if (!clean) {
			printf("cogwd did not exit cleanly (status %d)\n", d->exit_status);
			proc_dump_log(d->log_path, 60);
		}
	}
	if (d->has_notify) {
		notify_close(&d->ns);
		d->has_notify = false;
	}
	return d->exit_status;
}

static int remove_entry(const char *path, const struct stat *st, int type, struct FTW *ftw)
{
	(void)st;
	(void)type;
	(void)ftw;
	return remove(path);
}

void daemon_cleanup(daemon_run *d)
{
	daemon_stop(d, 10000);
	/* only directories this helper made (mkdtemp pattern) */
	if (strncmp(d->dir, "/tmp/cogw-it-", 13) == 0)
		nftw(d->dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
	d->dir[0] = '\0';
}

/* ---- cosim ---------------------------------------------------------------- */

static int device_node_id(const char *spec)
{
	const char *colon = strrchr(spec, ':');
	if (colon && colon[1] && strspn(colon + 1, "0123456789") == strlen(colon + 1))
		return atoi(colon + 1);
	FILE *f = fopen(spec, "r");
	if (!f)
		return -errno;
	char buf[65536];
	size_t n = fread(buf, 1, sizeof buf - 1, f);
	fclose(f);
	buf[n] = '\0';
	cJSON *root = cJSON_Parse(buf);
	int id = 1;
	const cJSON *item = root ? cJSON_GetObjectItemCaseSensitive(root, "node_id") : NULL;
	if (cJSON_IsNumber(item))
		id = item->valueint;
	else if (cJSON_IsString(item))
		id = (int)strtol(item->valuestring, NULL, 0);
	cJSON_Delete(root);
	return id;
}

int cosim_start(cosim_run *c, const char *dir, unsigned line, const char *const devices[],
		const char *const extra[])
{
	memset(c, 0, sizeof *c);
	c->exit_status = -1;
	c->line = line;
	snprintf(c->ctl_path, sizeof c->ctl_path, "%s/cosim%u.ctl", dir, line);
	snprintf(c->log_path, sizeof c->log_path, "%s/cosim%u.log", dir, line);
	char ifname[16];
	snprintf(ifname, sizeof ifname, "vcan%u", line);

	const char *argv[48];
	size_t argc = 0;
	argv[argc++] = DEFAULT_COSIM;
	argv[argc++] = "--interface";
	argv[argc++] = ifname;
	argv[argc++] = "--control";
	argv[argc++] = c->ctl_path;
	for (size_t i = 0; devices[i] && c->n_nodes < 8; i++) {
		int id = device_node_id(devices[i]);
		if (id <= 0 || id > 127)
			return id < 0 ? id : -EINVAL;
		c->node_ids[c->n_nodes++] = (uint8_t)id;
		argv[argc++] = "--device";
		argv[argc++] = devices[i];
	}
	bool silent = false; /* cable pulled from the start: no boot-up to wait for */
	for (size_t i = 0; extra && extra[i] && argc < 46; i++) {
		silent |= !strcmp(extra[i], "--silent");
		argv[argc++] = extra[i];
	}
	argv[argc] = NULL;

	/* listen before the start so that the boot-up frames are not missed */
	int fd = can_open_raw(ifname);
	if (fd < 0)
		return fd;
	c->pid = proc_spawn(argv, c->log_path, NULL);
	if (c->pid < 0) {
		c->pid = 0;
		close(fd);
		return -ECHILD;
	}
	int rc = 0;
	for (unsigned i = 0; i < c->n_nodes && rc == 0 && !silent; i++) {
		uint8_t data[8];
		int n = can_wait_id(fd, 0x700u + c->node_ids[i], data, 10000);
		if (n < 0) {
			/* a node's frames may interleave: the heartbeat comes later,
			 * so a missed boot-up of a second node is not an excuse */
			printf("cosim on %s: no boot-up of node %u\n", ifname, c->node_ids[i]);
			proc_dump_log(c->log_path, 20);
			rc = -ETIMEDOUT;
		} else if (n != 1 || data[0] != 0x00) {
			printf("cosim on %s: node %u first 700h frame is not a boot-up (len %d, "
			       "%02x)\n",
			       ifname, c->node_ids[i], n, data[0]);
			rc = -EPROTO;
		}
	}
	close(fd);
	/* the control socket is bound before the nodes boot; wait for the file
	 * anyway so that a test's first cosim_ctl cannot race it */
	uint64_t until = mono_ms() + 5000;
	while (rc == 0 && access(c->ctl_path, F_OK) != 0 && mono_ms() < until)
		sleep_ms(10);
	return rc;
}

int cosim_ctl(cosim_run *c, const char *cmd, char *reply, size_t cap, int timeout_ms)
{
	int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	if (fd < 0)
		return -errno;
	/* autobind an abstract address so that cosim can answer */
	sa_family_t fam = AF_UNIX;
	if (bind(fd, (struct sockaddr *)&fam, sizeof fam) != 0) {
		int e = -errno;
		close(fd);
		return e;
	}
	struct sockaddr_un to = { .sun_family = AF_UNIX };
	snprintf(to.sun_path, sizeof to.sun_path, "%s", c->ctl_path);
	if (sendto(fd, cmd, strlen(cmd), 0, (struct sockaddr *)&to, sizeof to) < 0) {
		int e = -errno;
		close(fd);
		return e;
	}
	struct pollfd p = { .fd = fd, .events = POLLIN };
	if (poll(&p, 1, timeout_ms) <= 0) {
		close(fd);
		return -ETIMEDOUT;
	}
	char buf[2048];
	ssize_t n = recv(fd, buf, sizeof buf - 1, 0);
	close(fd);
	if (n < 0)
		return -errno;
	buf[n] = '\0';
	if (reply)
		snprintf(reply, cap, "%s", buf);
	return strncmp(buf, "ok", 2) == 0 ? 0 : -EIO;
}

int cosim_stop(cosim_run *c, int timeout_ms)
{
	if (c->pid > 0) {
		c->exit_status = proc_stop(c->pid, SIGTERM, timeout_ms);
		c->pid = 0;
	}
	return c->exit_status;
}

/* ---- leftovers ------------------------------------------------------------ */

int daemon_leftovers(const char *instance, const pid_t *pids, size_t n_pids, char *report,
		     size_t cap)
{
	char prefix[64];
	snprintf(prefix, sizeof prefix, "cogw.%s.", instance);
	size_t plen = strlen(prefix);
	int count = 0;
	size_t used = 0;
	if (report && cap)
		report[0] = '\0';
#define REPORT(...)                                                               \
	do {                                                                      \
		if (report && used < cap) {                                       \
			int w = snprintf(report + used, cap - used, __VA_ARGS__); \
			if (w > 0)                                                \
				used += (size_t)w;                                \
		}                                                                 \
	} while (0)
	DIR *dir = opendir("/dev/mqueue");
	if (dir) {
		struct dirent *e;
		while ((e = readdir(dir)) != NULL) {
			if (strncmp(e->d_name, prefix, plen) != 0)
				continue;
			count++;
			REPORT("queue /%s; ", e->d_name);
		}
		closedir(dir);
	}
	for (size_t i = 0; i < n_pids; i++) {
		if (pids[i] <= 0)
			continue;
		int status;
		pid_t r = waitpid(pids[i], &status, WNOHANG);
		if (r == 0 || (r < 0 && errno == ECHILD && kill(pids[i], 0) == 0)) {
			count++;
			REPORT("process %d alive; ", (int)pids[i]);
		}
	}
#undef REPORT
	return count;
}
