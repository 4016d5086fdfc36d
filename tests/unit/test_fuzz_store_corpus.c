/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_fuzz_store_corpus.c - replays the fuzz corpus
 * tests/fuzz/corpus/store/ through the very fuzz target body
 * (tests/fuzz/fuzz_store.c, included below), so that the gcc sanitizer
 * build checks the same properties where clang/libFuzzer is not installed
 * (tests/fuzz/). Files named ok_* must be accepted, bad_* refused;
 * every prefix of every file is replayed too (cut-off writes and reads).
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */

#include "unity.h"

#include "tests/fuzz/fuzz_store.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepted(const uint8_t *data, size_t len)
{
	co_store_file_info info;

	return co_store_file_check(data, len, &info) == 0;
}

static void test_corpus_replay(void)
{
	/* Every file but the bad_* ones is named ok_* and must be accepted. */
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("store", fuzz_store_one, accepted) >= 5,
				 "corpus has fewer than 5 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
