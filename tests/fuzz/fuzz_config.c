/* SPDX-License-Identifier: MIT */
/*
 * tests/fuzz/fuzz_config.c - libFuzzer target for cogwd's JSON configuration
 * loader (apps/common/config.c, json_od.c, json_util.c).
 *
 * Properties checked on every input:
 * - load never crashes, leaks or reads out of bounds (ASan/UBSan);
 * - a refused input gives -EINVAL/-ENOMEM and a non-empty "source: ..."
 *   message, and leaves the config empty;
 * - an accepted config is a valid reload of itself with nothing to report.
 *
 * Built by `make fuzz` (clang only). tests/unit/test_config_corpus.c
 * includes this file and replays tests/fuzz/corpus/config/ with gcc, so
 * the same checks run in `make unit`.
 */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/config.h"

/* Returns 0 when every property holds, else a small number saying which
 * one failed (libFuzzer only sees the abort()). */
int fuzz_config_one(const uint8_t *data, size_t size);

int fuzz_config_one(const uint8_t *data, size_t size)
{
	static cogw_config cfg; /* large; not on the fuzzer's stack */
	char err[512] = "";
	char what[256];
	char *text = malloc(size + 1);
	int rc, bad = 0;

	if (!text)
		return 0;
	memcpy(text, data, size);
	text[size] = '\0';
	rc = cogw_config_load_string(&cfg, text, "fuzz", err, sizeof(err));
	if (rc) {
		if (rc != -EINVAL && rc != -ENOMEM)
			bad = 1;
		else if (strncmp(err, "fuzz: ", 6) != 0 || strlen(err) < 8)
			bad = 2;
		else if (cfg.n_lines != 0 || cfg.lines[0].od)
			bad = 3;
	} else {
		if (cfg.n_lines < 1 || cfg.n_lines > COGW_LINES_MAX)
			bad = 4;
		else if (!cogw_config_reload_check(&cfg, &cfg, what, sizeof(what)) || what[0])
			bad = 5;
	}
	cogw_config_free(&cfg);
	free(text);
	return bad;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (fuzz_config_one(data, size))
		abort();
	return 0;
}
