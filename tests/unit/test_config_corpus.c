/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_config_corpus.c - replays the fuzz corpus of the JSON
 * configuration loader (tests/fuzz/corpus/config/) through the very fuzz
 * target body (tests/fuzz/fuzz_config.c, included below), so that the gcc
 * sanitizer build checks the same properties where clang/libFuzzer is not
 * installed. Files named bad_* must be refused, the others accepted. Every
 * prefix of every file is replayed too (truncated uploads, cut-off writes).
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#include "tests/fuzz/fuzz_config.c"

void setUp(void) {}

void tearDown(void) {}

static char *read_all(const char *path, size_t *len)
{
	FILE *f = fopen(path, "rb");
	char *buf = NULL;
	long n;

	if (!f)
		return NULL;
	if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0 &&
	    (buf = malloc((size_t)n + 1)) && fread(buf, 1, (size_t)n, f) == (size_t)n) {
		buf[n] = '\0';
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
	DIR *d;
	unsigned files = 0;

	snprintf(dir, sizeof(dir), "%s%stests/fuzz/corpus/config", root ? root : "",
		 root ? "/" : "");
	d = opendir(dir);
	TEST_ASSERT_NOT_NULL_MESSAGE(d,
				     "corpus directory not found (run from the repository root)");
	while ((de = readdir(d))) {
		static cogw_config cfg;
		char err[512];
		size_t len = 0;
		char *text;
		int rc;

		if (de->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s", dir, de->d_name);
		text = read_all(path, &len);
		TEST_ASSERT_NOT_NULL_MESSAGE(text, path);
		files++;

		snprintf(msg, sizeof(msg), "%s: fuzz properties", de->d_name);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, fuzz_config_one((const uint8_t *)text, len), msg);
		rc = cogw_config_load_string(&cfg, text, de->d_name, err, sizeof(err));
		snprintf(msg, sizeof(msg), "%s: %s", de->d_name, rc ? err : "accepted");
		if (!strncmp(de->d_name, "bad_", 4))
			TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, rc, msg);
		else
			TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, msg);
		cogw_config_free(&cfg);

		for (size_t cut = 0; cut < len; cut++) {
			snprintf(msg, sizeof(msg), "%s cut at %zu", de->d_name, cut);
			TEST_ASSERT_EQUAL_INT_MESSAGE(
				0, fuzz_config_one((const uint8_t *)text, cut), msg);
		}
		free(text);
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
