/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_fuzz_dev_value_corpus.c - replays the fuzz corpus
 * tests/fuzz/corpus/dev_value/ through the very fuzz target body
 * (tests/fuzz/fuzz_dev_value.c, included below) in the gcc sanitizer
 * build. Files named bad_* hold a text their type refuses, the others one
 * it accepts; every prefix is replayed too.
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */

#include "unity.h"

#include "tests/fuzz/fuzz_dev_value.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepted(const uint8_t *data, size_t size)
{
	char text[FUZZ_TEXT_MAX + 1];
	uint8_t value[FUZZ_TEXT_MAX];
	size_t len;
	if (size < 1 || size - 1 > FUZZ_TEXT_MAX)
		return false;
	memcpy(text, data + 1, size - 1);
	text[size - 1] = '\0';
	return cogw_value_parse(data[0], text, value, sizeof value, &len) == 0;
}

static void test_corpus_replay(void)
{
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("dev_value", fuzz_dev_value_one, accepted) >= 10,
				 "corpus has fewer than 10 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
