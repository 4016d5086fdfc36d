/* SPDX-License-Identifier: MIT */
/*
 * apps/common/file_read.c - see file_read.h.
 */
#include "apps/common/file_read.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static int open_regular(const char *path, size_t max, struct stat *st, char *err, size_t errlen)
{
	/* O_NONBLOCK: opening a FIFO (or a device) for reading would wait for
	 * a writer for ever, and with it start-up, --check and a reload. The
	 * regular-file check below refuses it; for a regular file the flag
	 * changes nothing. */
	int fd = open(path, O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
	if (fd < 0) {
		int rc = errno == ENOENT ? -ENOENT : -EIO;
		snprintf(err, errlen, "%s: cannot open: %s", path, strerror(errno));
		return rc;
	}
	if (fstat(fd, st) < 0 || !S_ISREG(st->st_mode)) {
		snprintf(err, errlen, "%s: not a regular file", path);
		close(fd);
		return -EIO;
	}
	if ((uint64_t)st->st_size > max) {
		snprintf(err, errlen, "%s: %" PRIu64 " bytes, larger than %zu", path,
			 (uint64_t)st->st_size, max);
		close(fd);
		return -EFBIG;
	}
	return fd;
}

static double seconds_since(const struct timespec *t0)
{
	struct timespec t1;
	clock_gettime(CLOCK_MONOTONIC, &t1);
	return (double)(t1.tv_sec - t0->tv_sec) + (double)(t1.tv_nsec - t0->tv_nsec) / 1e9;
}

/* Read st_size bytes from fd (closed here) into a new buffer. */
static int read_all(int fd, const char *path, size_t size, uint8_t **out, char *err, size_t errlen)
{
	struct timespec t0;
	size_t got = 0;
	uint8_t *buf = malloc(size + 1);

	if (!buf) {
		close(fd);
		snprintf(err, errlen, "%s: out of memory", path);
		return -ENOMEM;
	}
	clock_gettime(CLOCK_MONOTONIC, &t0);
	while (got < size) {
		ssize_t n = read(fd, buf + got, size - got);
		if (seconds_since(&t0) > COGW_FILE_READ_TIMEOUT_S) {
			snprintf(err, errlen, "%s: reading took more than %d s", path,
				 COGW_FILE_READ_TIMEOUT_S);
			goto fail;
		}
		if (n < 0 && errno == EAGAIN) {
			struct timespec pause = { 0, 10000000 };
			nanosleep(&pause, NULL);
			continue;
		}
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0) {
			snprintf(err, errlen, "%s: read error: %s", path,
				 n < 0 ? strerror(errno) : "file shrank");
			goto fail;
		}
		got += (size_t)n;
	}
	close(fd);
	buf[got] = '\0';
	*out = buf;
	return 0;
fail:
	free(buf);
	close(fd);
	return -EIO;
}

int cogw_file_read(const char *path, size_t max, uint8_t **out, size_t *len, char *err,
		   size_t errlen)
{
	struct stat st;
	int fd, rc;

	*out = NULL;
	*len = 0;
	fd = open_regular(path, max, &st, err, errlen);
	if (fd < 0)
		return fd;
	rc = read_all(fd, path, (size_t)st.st_size, out, err, errlen);
	if (!rc)
		*len = (size_t)st.st_size;
	return rc;
}

int cogw_file_set_charge(cogw_file_set *s, const char *path, uint64_t bytes, char *err,
			 size_t errlen)
{
	if (bytes > s->limit - s->held) {
		snprintf(err, errlen,
			 "%s: %" PRIu64
			 " more bytes do not fit: the files named before hold %" PRIu64
			 " of file_memory %" PRIu64,
			 path, bytes, s->held, s->limit);
		return -ENOSPC;
	}
	s->held += bytes;
	return 0;
}

int cogw_file_set_get(cogw_file_set *s, const char *path, size_t max, cogw_file_bytes *out,
		      char *err, size_t errlen)
{
	struct stat st;
	cogw_file_entry *e;
	int fd, rc;

	fd = open_regular(path, max, &st, err, errlen);
	if (fd < 0)
		return fd;
	for (size_t i = 0; i < s->n; i++) {
		if (s->v[i].dev == st.st_dev && s->v[i].ino == st.st_ino &&
		    s->v[i].len == (size_t)st.st_size) {
			close(fd);
			*out = (cogw_file_bytes){ s->v[i].data, s->v[i].len };
			return 0;
		}
	}
	if ((rc = cogw_file_set_charge(s, path, (uint64_t)st.st_size, err, errlen))) {
		close(fd);
		return rc;
	}
	if (s->n == s->cap) {
		size_t cap = s->cap ? 2 * s->cap : 8;
		e = realloc(s->v, cap * sizeof(*e));
		if (!e) {
			close(fd);
			s->held -= (uint64_t)st.st_size;
			snprintf(err, errlen, "%s: out of memory", path);
			return -ENOMEM;
		}
		s->v = e;
		s->cap = cap;
	}
	e = &s->v[s->n];
	if ((rc = read_all(fd, path, (size_t)st.st_size, &e->data, err, errlen))) {
		s->held -= (uint64_t)st.st_size;
		return rc;
	}
	e->dev = st.st_dev;
	e->ino = st.st_ino;
	e->len = (size_t)st.st_size;
	s->n++;
	*out = (cogw_file_bytes){ e->data, e->len };
	return 0;
}

void cogw_file_set_free(cogw_file_set *s)
{
	if (!s)
		return;
	for (size_t i = 0; i < s->n; i++)
		free(s->v[i].data);
	free(s->v);
	memset(s, 0, sizeof(*s));
}
