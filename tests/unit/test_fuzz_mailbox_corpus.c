/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_fuzz_mailbox_corpus.c - replays the fuzz corpus
 * tests/fuzz/corpus/mailbox/ through the very fuzz target body
 * (tests/fuzz/fuzz_mailbox.c, included below), so that the gcc sanitizer
 * build checks the same properties where clang/libFuzzer is not installed
 * (tests/fuzz/). Files named valid_* must be accepted, bad_* refused;
 * every prefix of every file is replayed too (cut-off writes and reads).
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */

#include "unity.h"

#include "tests/fuzz/fuzz_mailbox.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepted(const uint8_t *data, size_t len)
{
	mbx_hdr h;

	if (mbx_hdr_decode(data, len, &h, NULL) != 0)
		return false;
	if (h.kind == MBX_KIND_EVENT) /* what a client checks before it hands one out */
		return mbx_event_validate(h.code, data + MBX_HDR_SIZE, h.len) == 0;
	return h.kind != MBX_KIND_COMMAND || mbx_cmd_validate(&h, data + MBX_HDR_SIZE, NULL) == 0;
}

static void test_corpus_replay(void)
{
	/* Every file but the bad_* ones is named valid_* and must be accepted. */
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("mailbox", fuzz_mailbox_one, accepted) >= 5,
				 "corpus has fewer than 5 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
