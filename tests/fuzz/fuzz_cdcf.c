/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_cdcf.c - libFuzzer target for the concise DCF parser
 * (core/cdcf.c), the bytes a manager downloads as a node's configuration.
 *
 * Properties checked on every input:
 * - check/iterate never crash or read out of bounds (ASan/UBSan);
 * - a refused input has an error, an offset inside the buffer, and a
 *   non-empty description;
 * - an accepted input iterates to exactly `count` entries, each inside the
 *   buffer and in order, and writing them again gives the same bytes.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_cdcf_corpus.c
 * includes this file and replays tests/fuzz/corpus/cdcf/ with gcc.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/cdcf.h"

int fuzz_cdcf_one(const uint8_t *data, size_t size);

int fuzz_cdcf_one(const uint8_t *data, size_t size)
{
	co_cdcf_diag d;
	co_cdcf_iter it;
	co_cdcf_entry e;
	co_cdcf_writer w;
	uint32_t count = 0, n = 0;
	size_t next = CO_CDCF_COUNT_SIZE;
	char text[256];
	uint8_t *copy;
	int bad = 0;

	if (co_cdcf_check(data, size, &count, &d)) {
		if (d.error == CO_CDCF_OK || d.offset > size)
			return 1;
		if (co_cdcf_diag_format(&d, text, sizeof(text)) <= 0 || !text[0])
			return 2;
		if (!co_cdcf_iter_init(&it, data, size, NULL) || co_cdcf_iter_next(&it, &e))
			return 3;
		return 0;
	}
	if (co_cdcf_iter_init(&it, data, size, NULL))
		return 4;
	copy = malloc(size ? size : 1);
	if (!copy)
		return 0;
	co_cdcf_writer_init(&w, copy, size);
	while (co_cdcf_iter_next(&it, &e)) {
		n++;
		if (e.number != n || e.offset != next || e.size == 0 || e.index == 0 ||
		    e.data != data + e.offset + CO_CDCF_HEADER_SIZE ||
		    e.offset + CO_CDCF_HEADER_SIZE + e.size > size) {
			bad = 5;
			break;
		}
		next = e.offset + CO_CDCF_HEADER_SIZE + e.size;
		if (co_cdcf_writer_add(&w, e.index, e.sub, e.data, e.size)) {
			bad = 6;
			break;
		}
	}
	if (!bad && n != count)
		bad = 7;
	if (!bad && (co_cdcf_writer_finish(&w) != (long)size || memcmp(copy, data, size)))
		bad = 8;
	free(copy);
	return bad;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_cdcf_one(data, size))
		abort();
	return 0;
}
