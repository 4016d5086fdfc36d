/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_ascii.c - libFuzzer target for the CiA 309-3 command
 * parser and value texts of cogw-ascii (apps/cogw-ascii/ascii_parse.c,
 * ascii_value.c): what any peer of the gateway's sockets can send.
 *
 * An input is a command line (first byte not 0xFF). Properties:
 * - parsing never crashes or reads out of bounds (ASan/UBSan);
 * - the result is OK or one of the 309-3 error numbers the parser may
 *   give (100, 101, 106, 107, 600);
 * - an accepted command is consistent: a write carries a type and at most
 *   the buffer's bytes, a fixed-size type exactly its size; an SDO command
 *   never addresses node 0 (that is "all" for NMT only);
 * - a write's value printed by the gateway and written again gives the
 *   very same bytes (what "r" prints, "w" takes back; NaNs aside).
 * An input starting with 0xFF is <type index> <value bytes>: the value is
 * printed, put into a write line and parsed back, same check.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_fuzz_ascii_corpus.c
 * includes this file and replays tests/fuzz/corpus/ascii/ with gcc.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogw-ascii/ascii_parse.h"

int fuzz_ascii_one(const uint8_t *data, size_t size);

#define FUZZ_VALUE_CAP 4096u

static bool is_nan_value(const ascii_type *t, const uint8_t *v)
{
	if (t->kind == ASCII_K_REAL32) {
		float f;

		memcpy(&f, v, 4);
		return isnan(f);
	}
	if (t->kind == ASCII_K_REAL64) {
		double d;

		memcpy(&d, v, 8);
		return isnan(d);
	}
	return false;
}

/* Print value v of type t, write it back through a "w" line: 0 if the
 * bytes come back unchanged. */
static int round_trip(const ascii_type *t, const uint8_t *v, size_t len)
{
	static char text[4 * FUZZ_VALUE_CAP + 64], line[4 * FUZZ_VALUE_CAP + 128];
	static uint8_t back[FUZZ_VALUE_CAP];
	ascii_cmd cmd;
	long n = ascii_value_format(t, v, len, text, sizeof text);

	if (n == -22 /* EINVAL */ || n < 0)
		return n == -74 /* EBADMSG: wrong size for the type */ ? 0 : 10;
	/* an answer line never carries a byte the gateway refuses as input */
	if (memchr(text, '\0', (size_t)n) || memchr(text, '\r', (size_t)n) ||
	    memchr(text, '\n', (size_t)n))
		return 14;
	if (is_nan_value(t, v))
		return 0;
	if (len == 0) /* an empty value prints as nothing: no "w" line can carry it */
		return 0;
	uint8_t time_value[6];
	if (t->kind == ASCII_K_TIME) {
		/* the 4 reserved bits are not shown; a millisecond count of a
		 * whole day or more (read from a device) is shown but no "w"
		 * accepts it */
		uint32_t ms = ((uint32_t)v[0] | (uint32_t)v[1] << 8 | (uint32_t)v[2] << 16 |
			       (uint32_t)v[3] << 24) &
			      0x0FFFFFFFu;
		if (ms >= 86400000u)
			return 0;
		memcpy(time_value, v, 6);
		time_value[3] &= 0x0F;
		v = time_value;
	}
	int ln = snprintf(line, sizeof line, "[7] 1 5 w 0x2000 1 %s %s", t->keyword, text);
	int rc = ascii_parse(line, (size_t)ln, &cmd, back, sizeof back);

	if (t->kind == ASCII_K_VSTRING && memchr(v, '#', len) == NULL &&
	    memchr(v, '\r', len) == NULL && memchr(v, '\n', len) == NULL &&
	    memchr(v, '\0', len) == NULL) {
		if (rc != ASCII_OK)
			return 11;
	} else if (t->kind == ASCII_K_VSTRING) {
		return 0; /* such strings are not expressible on one 309-3 line */
	}
	if (rc != ASCII_OK || cmd.verb != ASCII_V_WRITE || !cmd.has_seq || cmd.seq != 7)
		return 12;
	if (t->kind == ASCII_K_BOOL) /* any value but 0 reads as TRUE, written back as 1 */
		return cmd.data_len == 1 && back[0] == (v[0] != 0) ? 0 : 13;
	if (cmd.data_len != len || memcmp(back, v, len) != 0) {
		/* x-types and r-types print canonical forms; -0.0 stays -0.0 */
		return 13;
	}
	return 0;
}

int fuzz_ascii_one(const uint8_t *data, size_t size)
{
	static uint8_t buf[FUZZ_VALUE_CAP];
	ascii_cmd cmd;
	int rc;

	if (size >= 2 && data[0] == 0xFF) {
		size_t nt = 0;

		while (ascii_types[nt].keyword)
			nt++;
		const ascii_type *t = &ascii_types[data[1] % nt];
		size_t len = size - 2;

		if (len > FUZZ_VALUE_CAP / 2)
			len = FUZZ_VALUE_CAP / 2;
		if (t->size)
			len = len < t->size ? len : t->size;
		return round_trip(t, data + 2, len);
	}
	rc = ascii_parse((const char *)data, size, &cmd, buf, sizeof buf);
	switch (rc) {
	case ASCII_OK:
		break;
	case ASCII_E_UNSUPPORTED:
	case ASCII_E_SYNTAX:
	case ASCII_E_NET:
	case ASCII_E_NODE:
	case ASCII_E_MEMORY:
		return 0;
	default:
		return 1;
	}
	if (cmd.net > 127 || cmd.node > 127 || cmd.net == 0)
		return 2;
	if (cmd.verb == ASCII_V_WRITE) {
		if (!cmd.type || cmd.data_len > sizeof buf)
			return 3;
		if (cmd.type->size && cmd.data_len != cmd.type->size)
			return 4;
		if (round_trip(cmd.type, buf, cmd.data_len))
			return 5;
	}
	if ((cmd.verb == ASCII_V_READ || cmd.verb == ASCII_V_WRITE) && cmd.node == 0)
		return 6;
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_ascii_one(data, size) != 0)
		abort();
	return 0;
}
