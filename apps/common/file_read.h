/* SPDX-License-Identifier: MIT */
/*
 * apps/common/file_read.h - reading a file the configuration names (the
 * configuration itself, a node's DCF/EDS or concise DCF, a program image):
 * one treatment for all of them (docs/config.md "Files").
 *
 * - Regular files only: a FIFO, a device or a directory is refused. The file
 *   is opened with O_NONBLOCK, so opening a FIFO never waits for a writer
 *   (start-up, `cogwd --check` and a SIGHUP reload never hang on one).
 * - Bounded: a file above `max` bytes is refused before anything is read.
 * - Time-boxed: a file system that trickles (FUSE, a slow NFS server) is
 *   given COGW_FILE_READ_TIMEOUT_S in all.
 *
 * Main thread, start-up and reload only (allocates, blocks on the disk).
 */
#ifndef COGW_APPS_FILE_READ_H
#define COGW_APPS_FILE_READ_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#define COGW_FILE_READ_TIMEOUT_S 5

/* Read `path` whole into a malloc'd buffer with one NUL byte after the
 * contents (*len excludes it). Errors, with "path: reason" in err:
 * -ENOENT (no such file), -EIO (cannot open, not a regular file, read
 * error, too slow), -EFBIG (above max), -ENOMEM. */
int cogw_file_read(const char *path, size_t max, uint8_t **out, size_t *len, char *err,
		   size_t errlen);

/* The files one configuration loads, each once, with a ceiling on the bytes
 * they hold together (the `file_memory` key): two nodes naming the same file
 * (same device and inode, whatever the name) share its bytes. */
typedef struct cogw_file_entry {
	dev_t dev;
	ino_t ino;
	uint8_t *data; /* owned, NUL-terminated */
	size_t len;
} cogw_file_entry;

typedef struct cogw_file_set {
	cogw_file_entry *v;
	size_t n, cap;
	uint64_t held;  /* bytes counted against limit */
	uint64_t limit; /* 0 = nothing may be held */
} cogw_file_set;

/* A file's bytes as the set holds them. */
typedef struct cogw_file_bytes {
	const uint8_t *data; /* owned by the set, NUL-terminated */
	size_t len;
} cogw_file_bytes;

/* The bytes of `path` (at most max) into *out, read now or shared with an
 * earlier call for the same file. Errors as cogw_file_read, and -ENOSPC
 * when a new file does not fit in what is left of limit. */
int cogw_file_set_get(cogw_file_set *s, const char *path, size_t max, cogw_file_bytes *out,
		      char *err, size_t errlen);
/* Count bytes the caller holds because of a file (a copy, a conversion)
 * against the same limit: -ENOSPC (err says so) when they do not fit. */
int cogw_file_set_charge(cogw_file_set *s, const char *path, uint64_t bytes, char *err,
			 size_t errlen);
void cogw_file_set_free(cogw_file_set *s); /* accepts a zeroed set */

#endif /* COGW_APPS_FILE_READ_H */
