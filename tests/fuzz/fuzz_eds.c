/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_eds.c - libFuzzer target for the CiA 306 DCF/EDS reader
 * (apps/common/eds.c), which reads files an integrator hands to cogwd.
 *
 * Properties checked on every input:
 * - conversion never crashes, leaks or reads out of bounds (ASan/UBSan);
 * - a refused input gives -EINVAL (or -ENOMEM), no output, and a message
 *   "fuzz:LINE: reason" whose line is inside the input;
 * - an accepted input gives a concise DCF that passes co_cdcf_check with
 *   as many entries as the statistics say, and converting it again gives
 *   the same bytes (no hidden state);
 * - strict reading accepts nothing that lenient reading refuses, and
 *   refuses with the same "fuzz:LINE: reason" form.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_eds_corpus.c
 * includes this file and replays tests/fuzz/corpus/eds/ with gcc.
 */
#include <errno.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/eds.h"
#include "core/cdcf.h"

int fuzz_eds_one(const uint8_t *data, size_t size);

/* 0 when a refusal (rc, err) has the documented form. */
static int check_refusal(int rc, const uint8_t *out, size_t len, const char *err, size_t lines)
{
	unsigned long line;
	char *end;

	if (rc == -ENOMEM)
		return 0;
	if (rc != -EINVAL || out || len)
		return 1;
	if (strncmp(err, "fuzz:", 5))
		return 2;
	line = strtoul(err + 5, &end, 10);
	if (end == err + 5 || strncmp(end, ": ", 2) || strlen(end) < 3 || line > lines)
		return 3;
	return 0;
}

/* Strict reading refuses more, never less, than lenient reading. */
static int check_strict(const uint8_t *data, size_t size, bool lenient_accepted, size_t lines)
{
	eds_options strict = { .node_id = 5, .strict = true };
	char err[512] = "";
	uint8_t *out = NULL;
	size_t len = 0;
	int rc = eds_convert_opts((const char *)data, size, "fuzz", &strict, &out, &len, NULL, err,
				  sizeof(err));

	free(out);
	if (!rc)
		return lenient_accepted ? 0 : 6;
	return check_refusal(rc, out, len, err, lines) ? 7 : 0;
}

int fuzz_eds_one(const uint8_t *data, size_t size)
{
	char err[512] = "";
	uint8_t *out = NULL, *again = NULL;
	size_t len = 0, len2 = 0, lines = 1;
	eds_stats st;
	uint32_t count = 0;
	int rc, bad = 0;

	for (size_t i = 0; i < size; i++)
		lines += data[i] == '\n';
	rc = eds_convert((const char *)data, size, "fuzz", 5, &out, &len, &st, err, sizeof(err));
	if (rc == -ENOMEM)
		return 0;
	if (rc) {
		bad = check_refusal(rc, out, len, err, lines);
		return bad ? bad : check_strict(data, size, false, lines);
	}
	if (co_cdcf_check(out, len, &count, NULL) || count != st.entries)
		bad = 4;
	else if (eds_convert((const char *)data, size, "fuzz", 5, &again, &len2, NULL, err,
			     sizeof(err)) ||
		 len2 != len || memcmp(again, out, len))
		bad = 5;
	free(out);
	free(again);
	return bad ? bad : check_strict(data, size, true, lines);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_eds_one(data, size))
		abort();
	return 0;
}
