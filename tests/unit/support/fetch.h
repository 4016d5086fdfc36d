/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/fetch.h - run a scripts/fetch-*.sh (idempotent: it
 * returns at once when build/deps has its files already) and take the
 * directory it prints. Third-party test files are fetched, never
 * committed. Run from the repository root (make unit does).
 */
#ifndef COGW_TESTS_FETCH_H
#define COGW_TESTS_FETCH_H

#include <stddef.h>

/* The directory `script` printed, in dir; NULL when it failed. */
const char *fetch_deps_dir(const char *script, char *dir, size_t size);

#endif
