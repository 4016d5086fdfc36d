/* SPDX-License-Identifier: MIT */
/*
 * lines/file_atomic.h - replace a file so that a power cut leaves either
 * the old content or the new one, never a torn file: write a temp file
 * beside it, fsync, rename over, fsync the directory. Blocking file I/O:
 * never call it from a line thread.
 */
#ifndef COGW_LINES_FILE_ATOMIC_H
#define COGW_LINES_FILE_ATOMIC_H

#include <stddef.h>

/* Returns 0 or -errno (the old file is untouched on error). */
int file_write_atomic(const char *path, const void *buf, size_t len, unsigned mode);

#endif /* COGW_LINES_FILE_ATOMIC_H */
