/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_fuzz_ascii_corpus.c - replays the fuzz corpus
 * tests/fuzz/corpus/ascii/ through the very fuzz target body
 * (tests/fuzz/fuzz_ascii.c, included below), so that the gcc sanitizer
 * build checks the same properties where clang/libFuzzer is not
 * installed. Files named valid_* must parse, bad_* must be refused; every
 * prefix of every file is replayed too (a line cut anywhere). Files that
 * start with 0xFF are value round trips (see the target), valid_* too.
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */

#include "unity.h"

#include "tests/fuzz/fuzz_ascii.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepted(const uint8_t *data, size_t size)
{
	static uint8_t value[FUZZ_VALUE_CAP];
	ascii_cmd cmd;

	if (size >= 2 && data[0] == 0xFF) /* a value round trip, no line */
		return fuzz_ascii_one(data, size) == 0;
	return ascii_parse((const char *)data, size, &cmd, value, sizeof value) == ASCII_OK;
}

static void test_corpus_replay(void)
{
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("ascii", fuzz_ascii_one, accepted) >= 10,
				 "corpus has fewer than 10 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
