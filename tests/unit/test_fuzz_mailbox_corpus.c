/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_fuzz_mailbox_corpus.c - replays the fuzz corpus
 * tests/fuzz/corpus/mailbox/ through the very fuzz target body
 * (tests/fuzz/fuzz_mailbox.c, included below), so that the gcc sanitizer
 * build checks the same properties where clang/libFuzzer is not installed
 * (issue 11 item 10). Files named valid_* must be accepted, bad_* refused;
 * every prefix of every file is replayed too (cut-off writes and reads).
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#include "tests/fuzz/fuzz_mailbox.c"

void setUp(void) {}

void tearDown(void) {}

static bool accepted(const uint8_t *data, size_t len)
{
	mbx_hdr h;

	if (mbx_hdr_decode(data, len, &h, NULL) != 0)
		return false;
	return h.kind != MBX_KIND_COMMAND || mbx_cmd_validate(&h, data + MBX_HDR_SIZE, NULL) == 0;
}

#define CORPUS "mailbox"
#define GOOD_PREFIX "valid_"
#define FUZZ_ONE fuzz_mailbox_one

static uint8_t *read_all(const char *path, size_t *len)
{
	FILE *f = fopen(path, "rb");
	uint8_t *buf = NULL;
	long n;

	if (!f)
		return NULL;
	if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0 &&
	    (buf = malloc((size_t)n + 1)) && fread(buf, 1, (size_t)n, f) == (size_t)n) {
		*len = (size_t)n;
	} else {
		free(buf);
		buf = NULL;
	}
	fclose(f);
	return buf;
}

static void test_corpus_replay(void)
{
	const char *root = getenv("COGW_SRC_DIR");
	char dir[512], path[1024], msg[1200];
	struct dirent *de;
	unsigned files = 0;
	DIR *d;

	snprintf(dir, sizeof dir, "%s%stests/fuzz/corpus/" CORPUS, root ? root : "",
		 root ? "/" : "");
	d = opendir(dir);
	TEST_ASSERT_NOT_NULL_MESSAGE(d,
				     "corpus directory not found (run from the repository root)");
	while ((de = readdir(d))) {
		size_t len = 0;
		uint8_t *data;

		if (de->d_name[0] == '.')
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
		data = read_all(path, &len);
		TEST_ASSERT_NOT_NULL_MESSAGE(data, path);
		files++;
		snprintf(msg, sizeof msg, "%s: fuzz properties", de->d_name);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, FUZZ_ONE(data, len), msg);
		snprintf(msg, sizeof msg, "%s: %s", de->d_name,
			 strncmp(de->d_name, "bad_", 4) == 0 ? "must be refused"
							     : "must be accepted");
		if (strncmp(de->d_name, "bad_", 4) == 0)
			TEST_ASSERT_FALSE_MESSAGE(accepted(data, len), msg);
		else if (strncmp(de->d_name, GOOD_PREFIX, strlen(GOOD_PREFIX)) == 0)
			TEST_ASSERT_TRUE_MESSAGE(accepted(data, len), msg);
		for (size_t cut = 0; cut < len; cut++) {
			snprintf(msg, sizeof msg, "%s cut at %zu", de->d_name, cut);
			TEST_ASSERT_EQUAL_INT_MESSAGE(0, FUZZ_ONE(data, cut), msg);
		}
		free(data);
	}
	closedir(d);
	TEST_ASSERT_TRUE_MESSAGE(files >= 5, "corpus has fewer than 5 files");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	return UNITY_END();
}
