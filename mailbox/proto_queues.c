/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_queues.c - the names of the mailbox's POSIX message queues
 * (docs/mailbox.md "Queues"), what a client's pair of queue names must look
 * like, and the system limits the queues need (fs.mqueue, RLIMIT_MSGQUEUE).
 */
#include "mailbox/proto.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>

/* ---- names of queues ------------------------------------------------------ */

static bool qchar_ok(char c)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
	       c == '.' || c == '_' || c == '-';
}

bool mbx_queue_name_is_valid(const char *name, size_t field)
{
	size_t i;

	if (field > MBX_QNAME_MAX)
		field = MBX_QNAME_MAX;
	if (field < 3 || name[0] != '/')
		return false;
	for (i = 1; i < field && name[i]; i++)
		if (!qchar_ok(name[i]))
			return false;
	/* needs a NUL inside the field and at least one name char; "." and
	 * ".." are not names */
	if (i == field || i < 2)
		return false;
	if (strcmp(name, "/.") == 0 || strcmp(name, "/..") == 0)
		return false;
	return true;
}

/* The two queues of one client are named as one pair (docs/mailbox.md
 * "Security model"): a command queue of any line ("...cmd"), another
 * program's queue, or a client's event queue named as its response queue
 * (swapped or mixed) is no pair. */
bool mbx_client_queues_pair(const char *resp, const char *evt)
{
	static const char rs[] = ".resp", es[] = ".evt";
	size_t rn = strlen(resp), stem;

	if (rn <= sizeof rs || strcmp(resp + rn - (sizeof rs - 1), rs) != 0)
		return false;
	stem = rn - (sizeof rs - 1);
	return strlen(evt) == stem + sizeof es - 1 && strncmp(resp, evt, stem) == 0 &&
	       strcmp(evt + stem, es) == 0;
}

bool mbx_instance_is_valid(const char *instance)
{
	size_t i;

	if (!instance || !instance[0])
		return false;
	for (i = 0; instance[i]; i++) {
		char c = instance[i];

		if (i >= MBX_INSTANCE_MAX || c == '.' || !qchar_ok(c))
			return false;
	}
	return true;
}

int mbx_queue_name(char *buf, size_t cap, const char *instance, unsigned line)
{
	int n;

	if (!mbx_instance_is_valid(instance) || line >= MBX_LINES_MAX)
		return -EINVAL;
	n = snprintf(buf, cap, "/cogw.%s.line%u.cmd", instance, line);
	if (n < 0 || (size_t)n >= cap || (size_t)n >= MBX_QNAME_MAX)
		return -ENAMETOOLONG;
	return 0;
}

/* ---- system limits ---------------------------------------------------------- */

static int read_limit(const char *path, unsigned long *v)
{
	FILE *f = fopen(path, "re");
	int ok;

	if (!f)
		return -errno;
	ok = fscanf(f, "%lu", v);
	fclose(f);
	return ok == 1 ? 0 : -EIO;
}

/* Fail with rc, saying why in err (when the caller gave one). */
static int limit_error(char *err, size_t errlen, int rc, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

static int limit_error(char *err, size_t errlen, int rc, const char *fmt, ...)
{
	va_list ap;

	if (err) {
		va_start(ap, fmt);
		vsnprintf(err, errlen, fmt, ap);
		va_end(ap);
	}
	return rc;
}

int mbx_check_system_limits(unsigned depth, unsigned msgsize, char *err, size_t errlen)
{
	unsigned long msg_max, msgsize_max;
	struct rlimit rl;
	int rc;

	if (err && errlen)
		err[0] = 0;
	if (depth == 0 || msgsize < MBX_MSG_MIN || msgsize > MBX_MSG_MAX)
		return limit_error(err, errlen, -EINVAL,
				   "mailbox: depth %u / message size %u out of range"
				   " (depth >= 1, size %u..%u)",
				   depth, msgsize, MBX_MSG_MIN, MBX_MSG_MAX);
	rc = read_limit("/proc/sys/fs/mqueue/msg_max", &msg_max);
	if (rc == 0)
		rc = read_limit("/proc/sys/fs/mqueue/msgsize_max", &msgsize_max);
	if (rc)
		return limit_error(err, errlen, rc,
				   "mailbox: cannot read /proc/sys/fs/mqueue limits"
				   " (%s): is the mqueue file system available?",
				   strerror(-rc));
	if (depth > msg_max)
		return limit_error(err, errlen, -ERANGE,
				   "mailbox: fs.mqueue.msg_max is %lu but the mailbox"
				   " queue depth is %u: run 'sysctl -w"
				   " fs.mqueue.msg_max=%u' (or lower the depth)",
				   msg_max, depth, depth);
	if (msgsize > msgsize_max)
		return limit_error(err, errlen, -ERANGE,
				   "mailbox: fs.mqueue.msgsize_max is %lu but the"
				   " mailbox message size is %u: run 'sysctl -w"
				   " fs.mqueue.msgsize_max=%u' (or lower the size)",
				   msgsize_max, msgsize, msgsize);
	/* RLIMIT_MSGQUEUE counts the bytes of all queues of one user; the
	 * kernel charges about msgsize + a pointer per message. */
	if (getrlimit(RLIMIT_MSGQUEUE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) {
		unsigned long long need = (unsigned long long)depth *
					  (msgsize + sizeof(void *) * 2);

		if (need > rl.rlim_cur)
			return limit_error(err, errlen, -ERANGE,
					   "mailbox: RLIMIT_MSGQUEUE is %llu bytes but one"
					   " queue of %u x %u bytes needs %llu: raise it"
					   " (LimitMSGQUEUE= in the systemd unit, ulimit -q)",
					   (unsigned long long)rl.rlim_cur, depth, msgsize, need);
	}
	return 0;
}
