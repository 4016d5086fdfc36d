/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_dev_value.c - libFuzzer target for libcogw's device
 * object parsers (mailbox/client_api_values.c): a value's text as any
 * client (cogwctl, the ASCII gateway, the MQTT bridge) passes it on from
 * its users, and the DEV_LAYOUT / DEV_VALUE payloads a client receives.
 *
 * An input is <type> <text>: the first byte is a data type number (any:
 * the invalid ones must be refused), the rest a value's text. Properties:
 * - nothing crashes or reads out of bounds (ASan/UBSan);
 * - a text parsed as a fixed-size type gives exactly the type's size;
 * - what is parsed, printed and parsed again gives the same bytes (NaNs
 *   aside: REAL texts print them as "nan", which reads back as a NaN of
 *   another payload);
 * - the whole input as a DEV_LAYOUT answer is accepted only when its
 *   counts add up, and as a DEV_VALUE only when its length says so.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_fuzz_dev_value_corpus.c
 * includes this file and replays tests/fuzz/corpus/dev_value/ with gcc.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mailbox/cogw.h"

int fuzz_dev_value_one(const uint8_t *data, size_t size);

#define FUZZ_TEXT_MAX 512u

static bool is_nan(uint16_t type, const uint8_t *v)
{
	if (type == MBX_T_REAL32) {
		float f;
		memcpy(&f, v, 4);
		return isnan(f);
	}
	if (type == MBX_T_REAL64) {
		double d;
		memcpy(&d, v, 8);
		return isnan(d);
	}
	return false;
}

/* The payload walkers: whatever they accept is self-consistent. */
static int check_payloads(const uint8_t *data, size_t size)
{
	mbx_dev_value v;
	const uint8_t *value;
	if (cogw_dev_value_parse(data, size, &v, &value) == 0 &&
	    (size < sizeof v || v.len != size - sizeof v || value != data + sizeof v))
		return -1;
	int nodes = cogw_dev_layout_check(data, size);
	if (nodes != COGW_E_PROTOCOL && (nodes < 0 || (size_t)nodes * 32u > size))
		return -1;
	return 0;
}

int fuzz_dev_value_one(const uint8_t *data, size_t size)
{
	if (check_payloads(data, size) < 0)
		return -1;
	if (size < 1 || size - 1 > FUZZ_TEXT_MAX)
		return 0;
	uint16_t type = data[0];
	char text[FUZZ_TEXT_MAX + 1];
	memcpy(text, data + 1, size - 1);
	text[size - 1] = '\0';

	uint8_t value[FUZZ_TEXT_MAX], again[FUZZ_TEXT_MAX];
	size_t len = 0, len2 = 0;
	if (cogw_value_parse(type, text, value, sizeof value, &len) != 0)
		return 0;
	const cogw_type *t = cogw_type_of(type);
	if (!t || (t->size && len != t->size))
		return -1;
	char shown[FUZZ_TEXT_MAX * 3 + 8];
	int n = cogw_value_format(type, value, len, shown, sizeof shown);
	if (n < 0 || (size_t)n != strlen(shown))
		return -1;
	/* a string with a NUL in its text cannot come back the same */
	if (type == MBX_T_VISIBLE_STRING && memchr(value, 0, len))
		return 0;
	if (cogw_value_parse(type, shown, again, sizeof again, &len2) != 0 || len2 != len)
		return -1;
	if (!is_nan(type, value) && memcmp(value, again, len))
		return -1;
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_dev_value_one(data, size) != 0)
		abort();
	return 0;
}
