/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/corpus.h - replay a fuzz corpus
 * (tests/fuzz/corpus/<name>/) through a fuzz target body in the gcc
 * sanitizer build: every file and every prefix of it must keep the
 * target's properties (one() returns 0), files named bad_* must be
 * refused by accept() and the others accepted. Run from the repository
 * root (make unit does), or set COGW_SRC_DIR.
 */
#ifndef COGW_TESTS_CORPUS_H
#define COGW_TESTS_CORPUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef int (*corpus_one_fn)(const uint8_t *data, size_t size);
typedef bool (*corpus_accept_fn)(const uint8_t *data, size_t size);

/* Unity assertions inside; returns the number of files replayed. */
unsigned corpus_replay(const char *name, corpus_one_fn one, corpus_accept_fn accept);

#endif
