/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_eds_corpus.c - replays tests/fuzz/corpus/eds/ through
 * the DCF/EDS fuzz target body (tests/fuzz/fuzz_eds.c, included), so the
 * gcc sanitizer build checks the same properties where clang is not
 * installed; bad_* files must be refused, every prefix replayed.
 */
#include "unity.h"

#include "tests/fuzz/fuzz_eds.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepts(const uint8_t *data, size_t size)
{
	uint8_t *out = NULL;
	size_t len = 0;
	char err[512];
	int rc = eds_convert((const char *)data, size, "corpus", 5, &out, &len, NULL, err,
			     sizeof(err));

	free(out);
	if (rc)
		TEST_MESSAGE(err);
	return rc == 0;
}

static void test_corpus_replay(void)
{
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("eds", fuzz_eds_one, accepts) >= 8,
				 "corpus has fewer than 8 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
