/* SPDX-License-Identifier: MIT */
#include "tests/bench/support/bench.h"

#include "mailbox/cogw.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

void bench_print_figure(const bench_figure *f)
{
	printf("figure: %s = %.6g %s; ", f->name, f->value, f->unit);
	if (f->base_name)
		printf("baseline: %s = %.6g %s; ", f->base_name, f->base_value, f->base_unit);
	else
		printf("baseline: none; ");
	if (f->ratio >= 0)
		printf("ratio: %.3f; ", f->ratio);
	else
		printf("ratio: -; ");
	printf("target: %s; verdict: %s\n", f->target ? f->target : "none (context)",
	       f->verdict ? f->verdict : "-");
	fflush(stdout);
}

const char *bench_verdict(bool met)
{
	return met ? "met" : "not met";
}

void bench_note(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fputs("note: ", stdout);
	vprintf(fmt, ap);
	fputc('\n', stdout);
	va_end(ap);
	fflush(stdout);
}

uint64_t bench_now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

double bench_now_s(void)
{
	return (double)bench_now_ns() * 1e-9;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

double bench_percentile(double *v, size_t n, double p)
{
	if (!n)
		return 0;
	qsort(v, n, sizeof v[0], cmp_double);
	size_t rank = (size_t)(p / 100.0 * (double)n + 0.999999);
	if (rank < 1)
		rank = 1;
	if (rank > n)
		rank = n;
	return v[rank - 1];
}

bool bench_in_vm(void)
{
	const char *v = getenv("COGW_IN_VM");
	return v && strcmp(v, "1") == 0;
}

unsigned bench_mq_msg_max(void)
{
	FILE *f = fopen("/proc/sys/fs/mqueue/msg_max", "r");
	unsigned v = 10;
	if (f) {
		if (fscanf(f, "%u", &v) != 1)
			v = 10;
		fclose(f);
	}
	return v;
}

uint64_t bench_raise_mq_limit(void)
{
	struct rlimit rl = { RLIM_INFINITY, RLIM_INFINITY };
	if (setrlimit(RLIMIT_MSGQUEUE, &rl) != 0 && getrlimit(RLIMIT_MSGQUEUE, &rl) == 0) {
		rl.rlim_cur = rl.rlim_max;
		setrlimit(RLIMIT_MSGQUEUE, &rl);
	}
	getrlimit(RLIMIT_MSGQUEUE, &rl);
	return rl.rlim_cur == RLIM_INFINITY ? UINT64_MAX : (uint64_t)rl.rlim_cur;
}

/* One "Name:\tvalue" field of a status file already read into text. */
static uint64_t status_field(const char *text, const char *name)
{
	const char *at = strstr(text, name);
	return at ? strtoull(at + strlen(name), NULL, 10) : 0;
}

int bench_ctx_switches(pid_t pid, const char *thread, uint64_t *vol, uint64_t *invol)
{
	char path[64];
	snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
	DIR *d = opendir(path);
	struct dirent *e;
	*vol = *invol = 0;
	if (!d)
		return -1;
	while ((e = readdir(d)) != NULL) {
		char file[400], text[8192];
		if (e->d_name[0] == '.')
			continue;
		snprintf(file, sizeof file, "%s/%s/status", path, e->d_name);
		FILE *f = fopen(file, "r");
		if (!f)
			continue; /* the thread ended meanwhile */
		size_t n = fread(text, 1, sizeof text - 1, f);
		fclose(f);
		text[n] = '\0';
		char comm[32] = "";
		if (sscanf(text, "Name:\t%31s", comm) != 1 || (thread && strcmp(comm, thread) != 0))
			continue;
		*vol += status_field(text, "\nvoluntary_ctxt_switches:");
		*invol += status_field(text, "\nnonvoluntary_ctxt_switches:");
	}
	closedir(d);
	return 0;
}

const char *bench_program(const char *name, char *buf, size_t len)
{
	const char *dir = getenv("COGW_BENCH_BIN");
	snprintf(buf, len, "%s/%s", dir && *dir ? dir : "build/rel/bin", name);
	return buf;
}

int bench_tmpdir_create(char *dir, size_t len, const char *tag)
{
	snprintf(dir, len, "/tmp/cogw-bench-%s.XXXXXX", tag);
	return mkdtemp(dir) ? 0 : -errno;
}

int bench_setup(char *instance, size_t ilen, const char *prefix, char *dir, size_t dlen,
		const char *tag)
{
	signal(SIGPIPE, SIG_IGN);
	snprintf(instance, ilen, "%s%d", prefix, (int)getpid());
	return bench_tmpdir_create(dir, dlen, tag);
}

void bench_tmpdir_remove(const char *dir)
{
	DIR *d = opendir(dir);
	if (!d)
		return;
	struct dirent *e;
	char path[512];
	while ((e = readdir(d))) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		unlink(path);
	}
	closedir(d);
	rmdir(dir);
}

int bench_write_file(const char *path, const char *text)
{
	FILE *f = fopen(path, "w");
	if (!f)
		return -errno;
	size_t n = strlen(text);
	int rc = fwrite(text, 1, n, f) == n ? 0 : -EIO;
	if (fclose(f) != 0)
		rc = -EIO;
	return rc;
}

void bench_unlink_instance_queues(const char *instance)
{
	DIR *d = opendir("/dev/mqueue");
	if (!d || !instance || !*instance) {
		if (d)
			closedir(d);
		return;
	}
	char prefix[64], name[300];
	snprintf(prefix, sizeof prefix, "cogw.%s.", instance);
	struct dirent *e;
	while ((e = readdir(d))) {
		if (strncmp(e->d_name, prefix, strlen(prefix)) == 0) {
			snprintf(name, sizeof name, "/%s", e->d_name);
			mq_unlink(name);
		}
	}
	closedir(d);
}

int bench_daemon_start(bench_daemon *d, const char *config_path, const char *instance,
		       const char *log_path)
{
	char prog[256];
	memset(d, 0, sizeof *d);
	d->pid = -1;
	snprintf(d->instance, sizeof d->instance, "%s", instance);
	snprintf(d->log, sizeof d->log, "%s", log_path);
	if (notify_open(&d->ns) < 0) {
		printf("bench: cannot open a NOTIFY_SOCKET\n");
		return -1;
	}
	const char *argv[] = { bench_program("cogwd", prog, sizeof prog), "--config", config_path,
			       NULL };
	const char *env[] = { d->ns.env, NULL };
	d->pid = proc_spawn(argv, log_path, env);
	if (d->pid < 0 || notify_wait(&d->ns, "READY=1", 20000, NULL, 0) < 0) {
		printf("bench: cogwd did not report READY=1 within 20 s\n");
		proc_dump_log(log_path, 20);
		bench_daemon_stop(d);
		return -1;
	}
	/* Nobody reads the socket after READY=1 (systemd would): close it, so
	 * that the daemon's later STATUS= updates fail at once instead of
	 * blocking its main thread on a full socket queue. */
	notify_close(&d->ns);
	return 0;
}

void bench_daemon_stop(bench_daemon *d)
{
	if (d->pid > 0) {
		int st = proc_stop(d->pid, SIGTERM, 10000);
		if (st < 0 || !WIFEXITED(st) || WEXITSTATUS(st) != 0) {
			printf("bench: cogwd did not exit cleanly (status 0x%x)\n", (unsigned)st);
			proc_dump_log(d->log, 20);
		}
		d->pid = -1;
	}
	notify_close(&d->ns);
	bench_unlink_instance_queues(d->instance);
}

static bool read_text(const char *path, char *buf, size_t len)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return false;
	ssize_t n = read(fd, buf, len - 1);
	close(fd);
	if (n <= 0)
		return false;
	buf[n] = '\0';
	return true;
}

double bench_thread_cpu_s(pid_t pid, pid_t tid)
{
	char path[128], buf[1024];
	unsigned long long run_ns;
	snprintf(path, sizeof path, "/proc/%d/task/%d/schedstat", (int)pid, (int)tid);
	if (read_text(path, buf, sizeof buf) && sscanf(buf, "%llu", &run_ns) == 1)
		return (double)run_ns * 1e-9;
	snprintf(path, sizeof path, "/proc/%d/task/%d/stat", (int)pid, (int)tid);
	if (!read_text(path, buf, sizeof buf))
		return -1;
	/* the name (field 2) may hold blanks: fields count from its ')' */
	const char *p = strrchr(buf, ')');
	unsigned long long utime, stime;
	if (!p || sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &utime,
			 &stime) != 2)
		return -1;
	return (double)(utime + stime) / (double)sysconf(_SC_CLK_TCK);
}

pid_t bench_find_thread(pid_t pid, const char *comm)
{
	char path[320], buf[64];
	snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
	DIR *d = opendir(path);
	if (!d)
		return -1;
	pid_t found = -1;
	struct dirent *e;
	while (found < 0 && (e = readdir(d))) {
		if (e->d_name[0] < '0' || e->d_name[0] > '9')
			continue;
		snprintf(path, sizeof path, "/proc/%d/task/%s/comm", (int)pid, e->d_name);
		if (read_text(path, buf, sizeof buf)) {
			buf[strcspn(buf, "\n")] = '\0';
			if (strcmp(buf, comm) == 0)
				found = (pid_t)atoi(e->d_name);
		}
	}
	closedir(d);
	return found;
}

double bench_process_cpu_s(pid_t pid)
{
	char path[320];
	snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
	DIR *d = opendir(path);
	if (!d)
		return -1;
	double sum = 0;
	struct dirent *e;
	while ((e = readdir(d))) {
		if (e->d_name[0] < '0' || e->d_name[0] > '9')
			continue;
		double t = bench_thread_cpu_s(pid, (pid_t)atoi(e->d_name));
		if (t > 0)
			sum += t;
	}
	closedir(d);
	return sum;
}

int bench_write_tpdo_eds(const char *path, int tpdos)
{
	char t[16384];
	size_t n = 0;
	n += (size_t)snprintf(
		t + n, sizeof t - n,
		"[FileInfo]\nFileName=bench.eds\nFileVersion=1\nEDSVersion=4.0\n"
		"[DeviceInfo]\nVendorName=cogw bench\nProductName=event-driven TPDOs\n"
		"NrOfRXPDO=0\nNrOfTXPDO=%d\n"
		"[MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n"
		"[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\n"
		"AccessType=ro\nDefaultValue=0x00040191\nPDOMapping=0\n"
		"[1001]\nParameterName=Error register\nObjectType=0x7\n"
		"DataType=0x0005\nAccessType=ro\nDefaultValue=0\nPDOMapping=1\n"
		"[1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=2\n"
		"[1018sub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\n"
		"AccessType=ro\nDefaultValue=1\nPDOMapping=0\n"
		"[1018sub1]\nParameterName=Vendor\nObjectType=0x7\nDataType=0x0007\n"
		"AccessType=ro\nDefaultValue=0x0B16C0DE\nPDOMapping=0\n"
		"[OptionalObjects]\nSupportedObjects=%d\n",
		tpdos, 2 * tpdos + 1);
	for (int p = 0; p < tpdos; p++)
		n += (size_t)snprintf(t + n, sizeof t - n, "%d=0x%04X\n%d=0x%04X\n", 2 * p + 1,
				      0x1800 + p, 2 * p + 2, 0x1A00 + p);
	n += (size_t)snprintf(t + n, sizeof t - n, "%d=0x6401\n", 2 * tpdos + 1);
	for (int p = 0; p < tpdos; p++) {
		n += (size_t)snprintf(
			t + n, sizeof t - n,
			"[%04X]\nParameterName=TPDO %d communication\nObjectType=0x9\nSubNumber=3\n"
			"[%04Xsub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\n"
			"AccessType=ro\nDefaultValue=2\nPDOMapping=0\n"
			"[%04Xsub1]\nParameterName=COB-ID\nObjectType=0x7\nDataType=0x0007\n"
			"AccessType=rw\nDefaultValue=$NODEID+0x%03X\nPDOMapping=0\n"
			"[%04Xsub2]\nParameterName=transmission type\nObjectType=0x7\n"
			"DataType=0x0005\nAccessType=rw\nDefaultValue=254\nPDOMapping=0\n",
			0x1800 + p, p + 1, 0x1800 + p, 0x1800 + p, 0x180 + 0x100 * p, 0x1800 + p);
		n += (size_t)snprintf(
			t + n, sizeof t - n,
			"[%04X]\nParameterName=TPDO %d mapping\nObjectType=0x9\n"
			"SubNumber=5\n[%04Xsub0]\nParameterName=n\nObjectType=0x7\n"
			"DataType=0x0005\nAccessType=rw\nDefaultValue=4\nPDOMapping=0\n",
			0x1A00 + p, p + 1, 0x1A00 + p);
		for (int e = 1; e <= 4; e++)
			n += (size_t)snprintf(
				t + n, sizeof t - n,
				"[%04Xsub%d]\nParameterName=entry %d\nObjectType=0x7\n"
				"DataType=0x0007\nAccessType=rw\n"
				"DefaultValue=0x6401%02X10\nPDOMapping=0\n",
				0x1A00 + p, e, e, 4 * p + e);
	}
	n += (size_t)snprintf(t + n, sizeof t - n,
			      "[6401]\nParameterName=analogue inputs\nObjectType=0x8\n"
			      "SubNumber=%d\n[6401sub0]\nParameterName=n\nObjectType=0x7\n"
			      "DataType=0x0005\nAccessType=ro\nDefaultValue=%d\nPDOMapping=0\n",
			      4 * tpdos + 1, 4 * tpdos);
	for (int s = 1; s <= 4 * tpdos; s++)
		n += (size_t)snprintf(
			t + n, sizeof t - n,
			"[6401sub%X]\nParameterName=input %d\nObjectType=0x7\n"
			"DataType=0x0003\nAccessType=ro\nDefaultValue=0\nPDOMapping=1\n",
			s, s);
	if (n >= sizeof t)
		return -ENOSPC;
	return bench_write_file(path, t);
}

int bench_go_operational(cogw *h, uint8_t node_id)
{
	int fd = can_open_raw("vcan0");
	uint8_t start[2] = { 0x01, node_id };

	if (fd < 0 || can_send_std(fd, 0x000, start, 2) < 0) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	close(fd);
	for (uint64_t until = mono_ms() + 5000; mono_ms() < until; sleep_ms(20)) {
		mbx_line_status st;

		if (cogw_line_status(h, 0, &st, 5000) == 0 && st.nmt_state == 0x05)
			return 0;
	}
	printf("the daemon's node %u did not become operational\n", node_id);
	return -1;
}
