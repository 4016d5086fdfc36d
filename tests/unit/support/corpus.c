/* SPDX-License-Identifier: MIT */
#include "tests/unit/support/corpus.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

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

unsigned corpus_replay(const char *name, corpus_one_fn one, corpus_accept_fn accept)
{
	const char *root = getenv("COGW_SRC_DIR");
	char dir[512], path[1024], msg[1200];
	struct dirent *de;
	unsigned files = 0;
	DIR *d;

	snprintf(dir, sizeof(dir), "%s%stests/fuzz/corpus/%s", root ? root : "", root ? "/" : "",
		 name);
	d = opendir(dir);
	TEST_ASSERT_NOT_NULL_MESSAGE(d,
				     "corpus directory not found (run from the repository root)");
	while ((de = readdir(d))) {
		size_t len = 0;
		uint8_t *data;

		if (de->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s", dir, de->d_name);
		data = read_all(path, &len);
		TEST_ASSERT_NOT_NULL_MESSAGE(data, path);
		files++;
		snprintf(msg, sizeof(msg), "%s: fuzz properties", de->d_name);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, one(data, len), msg);
		snprintf(msg, sizeof(msg), "%s: %s", de->d_name,
			 strncmp(de->d_name, "bad_", 4) ? "must be accepted" : "must be refused");
		TEST_ASSERT_EQUAL_MESSAGE(!!strncmp(de->d_name, "bad_", 4), accept(data, len), msg);
		for (size_t cut = 0; cut < len; cut++) {
			snprintf(msg, sizeof(msg), "%s cut at %zu", de->d_name, cut);
			TEST_ASSERT_EQUAL_INT_MESSAGE(0, one(data, cut), msg);
		}
		free(data);
	}
	closedir(d);
	return files;
}
