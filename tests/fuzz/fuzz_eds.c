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
 *   refuses with the same "fuzz:LINE: reason" form;
 * - the PDO layout of an accepted file (apps/common/eds_pdo.h, read from
 *   the same conversion) is refused only with "fuzz: ..." and otherwise
 *   holds valid PDOs whose mappings fit a classic CAN frame.
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
#include "apps/common/eds_pdo.h"
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
	eds_result res;
	int rc = eds_convert_opts((const char *)data, size, "fuzz", &strict, &res);

	free(res.cdcf);
	if (!rc)
		return lenient_accepted ? 0 : 6;
	return check_refusal(rc, res.cdcf, res.len, res.err, lines) ? 7 : 0;
}

/* 0 when the layout the reader collected is refused in the documented
 * form or fits CiA 301's limits. */
static int check_layout(eds_pdo_reader *r)
{
	eds_pdo_file f;
	eds_pdo_types types = { 0 };
	char err[512] = "";
	int bad = 0, rc = eds_pdo_reader_finish(r, "fuzz", &f, &types, err, sizeof(err));

	if (rc == -ENOMEM)
		return 0;
	if (rc)
		return rc == -EINVAL && !strncmp(err, "fuzz: ", 6) ? 0 : 8;
	for (unsigned d = 0; d < 2 && !bad; d++)
		for (unsigned k = 0; k < f.n[d] && !bad; k++) {
			const co_pdo_layout_pdo *p = &f.pdo[d][k];
			if (p->cob >> 31 || p->n > CO_PDO_MAX_MAP || p->bytes > 8 || !p->nr)
				bad = 9;
		}
	for (size_t i = 1; i < types.n && !bad; i++)
		if (((uint32_t)types.list[i - 1].index << 8 | types.list[i - 1].sub) >
		    ((uint32_t)types.list[i].index << 8 | types.list[i].sub))
			bad = 10;
	eds_pdo_file_free(&f);
	free(types.list);
	return bad;
}

int fuzz_eds_one(const uint8_t *data, size_t size)
{
	eds_pdo_reader reader = { 0 };
	eds_options with_layout = { .node_id = 5,
				    .on_entry = eds_pdo_reader_on_entry,
				    .entry_arg = &reader };
	eds_result res, again = { 0 };
	size_t lines = 1;
	uint32_t count = 0;
	int rc, bad = 0;

	for (size_t i = 0; i < size; i++)
		lines += data[i] == '\n';
	rc = eds_convert((const char *)data, size, "fuzz", 5, &res);
	if (rc == -ENOMEM)
		return 0;
	if (rc) {
		bad = check_refusal(rc, res.cdcf, res.len, res.err, lines);
		return bad ? bad : check_strict(data, size, false, lines);
	}
	if (co_cdcf_check(res.cdcf, res.len, &count, NULL) || count != res.stats.entries)
		bad = 4;
	else if (eds_convert_opts((const char *)data, size, "fuzz", &with_layout, &again) ||
		 again.len != res.len || memcmp(again.cdcf, res.cdcf, res.len))
		bad = 5;
	else
		bad = check_layout(&reader);
	eds_pdo_reader_free(&reader);
	free(res.cdcf);
	free(again.cdcf);
	return bad ? bad : check_strict(data, size, true, lines);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_eds_one(data, size))
		abort();
	return 0;
}
