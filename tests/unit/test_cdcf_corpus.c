/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_cdcf_corpus.c - replays tests/fuzz/corpus/cdcf/ through
 * the concise DCF fuzz target body (tests/fuzz/fuzz_cdcf.c, included), so
 * the gcc sanitizer build checks the same properties where clang is not
 * installed; bad_* files must be refused, every prefix replayed.
 */
#include "unity.h"

#include "tests/fuzz/fuzz_cdcf.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepts(const uint8_t *data, size_t size)
{
	return co_cdcf_check(data, size, NULL, NULL) == 0;
}

static void test_corpus_replay(void)
{
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("cdcf", fuzz_cdcf_one, accepts) >= 8,
				 "corpus has fewer than 8 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
