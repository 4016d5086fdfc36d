/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_store.c - libFuzzer target for the stored-parameter
 * format: a saved file (core/store_file.h seal around a core/od_image.h
 * image), as cogwd reads it from its state directory at start-up.
 *
 * Properties checked on every input:
 * - checking and applying never crash or read out of bounds (ASan/UBSan);
 * - an accepted file is exactly image + trailer: sealing its image again
 *   with the same generation and set gives the very same bytes;
 * - no flipped bit in an accepted file is accepted (the first 256 bytes
 *   and the whole trailer are tried);
 * - only an accepted file's image is applied (to a standard communication
 *   dictionary): records are checked against the dictionary, never
 *   trusted, and the counts add up.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_fuzz_corpora.c
 * includes this file and replays tests/fuzz/corpus/store/ with gcc.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/od.h"
#include "core/od_image.h"
#include "core/od_std.h"
#include "core/store_file.h"

int fuzz_store_one(const uint8_t *data, size_t size);

static int flip_refused(uint8_t *buf, size_t size, size_t at)
{
	co_store_file_info info;
	int ok = 1;

	for (int b = 0; b < 8 && ok; b++) {
		buf[at] ^= (uint8_t)(1u << b);
		ok = co_store_file_check(buf, size, &info) != 0;
		buf[at] ^= (uint8_t)(1u << b);
	}
	return ok;
}

int fuzz_store_one(const uint8_t *data, size_t size)
{
	static co_od *od;
	co_store_file_info info;
	uint8_t *copy;
	int bad = 0;

	if (!od && (co_od_create(&od, 256) < 0 || co_od_add_std_comm(od, 5, NULL) < 0))
		return 0;
	if (co_store_file_check(data, size, &info) != 0)
		return 0; /* refused: nothing is applied (line_store.c) */
	if (info.image_len + CO_STORE_FILE_TRAILER != size)
		return 1;
	copy = malloc(size);
	if (!copy)
		return 0;
	memcpy(copy, data, size);
	if (co_store_file_seal(copy, info.image_len, size, info.generation, info.set) !=
		    (long)size ||
	    memcmp(copy, data, size) != 0)
		bad = 2;
	for (size_t i = 0; !bad && i < size; i++) {
		if (i >= 256 && i < info.image_len)
			continue;
		if (!flip_refused(copy, size, i))
			bad = 3;
	}
	unsigned applied = 0, skipped = 0;
	int rc = co_od_image_apply(od, data, info.image_len, CO_OD_IMAGE_SET_VALUE, &applied,
				   &skipped);

	if (!bad && rc == 0 && applied + skipped > info.image_len)
		bad = 4;
	free(copy);
	return bad;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_store_one(data, size))
		abort();
	return 0;
}
