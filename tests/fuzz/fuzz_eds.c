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
 *   the same bytes (no hidden state).
 *
 * Built by `make fuzz` (clang only). tests/unit/test_eds_corpus.c
 * includes this file and replays tests/fuzz/corpus/eds/ with gcc.
 */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/eds.h"
#include "core/cdcf.h"

int fuzz_eds_one(const uint8_t *data, size_t size);

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
	if (rc) {
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
	if (co_cdcf_check(out, len, &count, NULL) || count != st.entries)
		bad = 4;
	else if (eds_convert((const char *)data, size, "fuzz", 5, &again, &len2, NULL, err,
			     sizeof(err)) ||
		 len2 != len || memcmp(again, out, len))
		bad = 5;
	free(out);
	free(again);
	return bad;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_eds_one(data, size))
		abort();
	return 0;
}
