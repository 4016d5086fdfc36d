/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_cogwctl_dcf.c - the offline tool "cogwctl dcf":
 * the real program (sanitizer build) run on files in a temporary
 * directory: check and convert of a DCF, the written concise DCF checked
 * byte by byte, a refused file with its line, usage errors and exit
 * codes, --json, and a vendor EDS this project did not write.
 * Needs no daemon and no CAN.
 */
#include <cjson/cJSON.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/cdcf.h"
#include "unity.h"

#define CTL "build/san/bin/cogwctl"

static char dir[64];

typedef struct ctl_result {
	int exit;
	char out[65536];
	char err[4096];
} ctl_result;

static ctl_result res;

static size_t slurp(const char *path, char *buf, size_t cap)
{
	buf[0] = '\0';
	FILE *f = fopen(path, "rb");
	if (!f)
		return 0;
	size_t n = fread(buf, 1, cap - 1, f);
	buf[n] = '\0';
	fclose(f);
	return n;
}

static ctl_result *ctl_run(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static ctl_result *ctl_run(const char *fmt, ...)
{
	char args[1024], cmd[1400];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(args, sizeof args, fmt, ap);
	va_end(ap);
	snprintf(cmd, sizeof cmd, "%s %s >%s/ctl.out 2>%s/ctl.err", CTL, args, dir, dir);
	int st = system(cmd);
	res.exit = (st != -1 && WIFEXITED(st)) ? WEXITSTATUS(st) : -1;
	snprintf(cmd, sizeof cmd, "%s/ctl.out", dir);
	slurp(cmd, res.out, sizeof res.out);
	snprintf(cmd, sizeof cmd, "%s/ctl.err", dir);
	slurp(cmd, res.err, sizeof res.err);
	return &res;
}

static void put(const char *name, const char *text)
{
	char path[128];
	snprintf(path, sizeof path, "%s/%s", dir, name);
	FILE *f = fopen(path, "w");
	TEST_ASSERT_NOT_NULL(f);
	fputs(text, f);
	fclose(f);
}

void setUp(void)
{
	snprintf(dir, sizeof dir, "/tmp/test_cogwctl_dcf_XXXXXX");
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, access(CTL, X_OK),
				      "build/san/bin/cogwctl missing (make tests-build)");
}

void tearDown(void)
{
	char cmd[128];
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	TEST_ASSERT_EQUAL_INT(0, system(cmd));
}

static const char *dcf_text =
	"[FileInfo]\nFileName=dev.dcf\n"
	"[DeviceComissioning]\nNodeID=3\n"
	"[OptionalObjects]\nSupportedObjects=3\n1=0x1017\n2=0x1800\n3=0x1A00\n"
	"[1017]\nDataType=0x0006\nAccessType=rw\nDefaultValue=0\nParameterValue=250\n"
	"[1800]\nObjectType=9\nSubNumber=3\n"
	"[1800sub0]\nDataType=5\nAccessType=const\nDefaultValue=5\n"
	"[1800sub1]\nDataType=7\nAccessType=rw\nDefaultValue=$NODEID+0x180\n"
	"[1800sub5]\nDataType=6\nAccessType=rw\nDefaultValue=100\n"
	"[1A00]\nObjectType=9\nSubNumber=2\n"
	"[1A00sub0]\nDataType=5\nAccessType=rw\nDefaultValue=1\n"
	"[1A00sub1]\nDataType=7\nAccessType=rw\nDefaultValue=0x61300120\n";

static void test_check_and_convert(void)
{
	put("dev.dcf", dcf_text);
	ctl_run("dcf check %s/dev.dcf --list", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(
		strstr(res.out,
		       "ok: 3 objects, 6 values, 7 entries for the concise DCF (71 bytes), node 3"),
		res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "1800:01       4 bytes  83 01 00 80"),
				     res.out);

	/* --node overrides the file's NodeID */
	ctl_run("dcf convert %s/dev.dcf --node 5 -o %s/dev.cdc", dir, dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	char want_line[160];
	snprintf(want_line, sizeof want_line, "wrote %s/dev.cdc", dir);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, want_line), res.out);

	static uint8_t buf[4096];
	char path[128];
	snprintf(path, sizeof path, "%s/dev.cdc", dir);
	size_t n = slurp(path, (char *)buf, sizeof buf);
	co_cdcf_iter it;
	co_cdcf_entry e;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, buf, n, NULL));
	static const struct {
		uint16_t index;
		uint8_t sub;
		uint32_t size, value;
	} want[] = {
		{ 0x1017, 0, 2, 250 },   { 0x1800, 1, 4, 0x80000185 }, { 0x1800, 5, 2, 100 },
		{ 0x1A00, 0, 1, 0 },     { 0x1A00, 1, 4, 0x61300120 }, { 0x1A00, 0, 1, 1 },
		{ 0x1800, 1, 4, 0x185 },
	};
	TEST_ASSERT_EQUAL_UINT32(sizeof want / sizeof want[0], it.count);
	for (size_t i = 0; co_cdcf_iter_next(&it, &e); i++) {
		uint32_t v = 0;
		for (uint32_t b = 0; b < e.size; b++)
			v |= (uint32_t)e.data[b] << (8 * b);
		TEST_ASSERT_EQUAL_HEX16(want[i].index, e.index);
		TEST_ASSERT_EQUAL_HEX8(want[i].sub, e.sub);
		TEST_ASSERT_EQUAL_UINT32(want[i].size, e.size);
		TEST_ASSERT_EQUAL_HEX32(want[i].value, v);
	}

	/* the written file checks as a concise DCF */
	ctl_run("dcf check %s/dev.cdc", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "concise DCF ok: 7 entries"), res.out);
	/* cut short: refused, naming the entry */
	FILE *f = fopen(path, "wb");
	fwrite(buf, 1, n - 3, f);
	fclose(f);
	ctl_run("dcf check %s/dev.cdc", dir);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "not a concise DCF: entry 7 of 7 (1800:01)"),
				     res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "data cut short (size 4, 1 bytes left)"),
				     res.err);
}

static void test_refused_file_names_the_line(void)
{
	/* a configured value that does not fit: refused */
	put("bad.dcf", "[2000]\nDataType=0x0005\nAccessType=rw\nParameterValue=256\n");
	ctl_run("dcf check %s/bad.dcf", dir);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	char want[1024];
	snprintf(
		want, sizeof want,
		"cogwctl dcf check: %s/bad.dcf:4: ParameterValue '256': out of range for UNSIGNED8 "
		"(max 255)\n",
		dir);
	TEST_ASSERT_EQUAL_STRING(want, res.err);

	ctl_run("--json dcf check %s/bad.dcf", dir);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	TEST_ASSERT_TRUE(cJSON_IsFalse(cJSON_GetObjectItem(o, "ok")));
	TEST_ASSERT_NOT_NULL(strstr(cJSON_GetObjectItem(o, "error")->valuestring, "bad.dcf:4: "));
	cJSON_Delete(o);

	/* a default value that does not fit: left out with a warning naming
	 * the line, every warning printed; --strict refuses the file */
	put("bad.eds", "[2000]\nDataType=0x0005\nAccessType=rw\nDefaultValue=256\n"
		       "[2001]\nObjectType=0x8\nSubNumber=3\n[2001sub0]\nDataType=5\n"
		       "AccessType=ro\nDefaultValue=1\n[2001sub1]\nDataType=9\nAccessType=rw\n"
		       "DefaultValue=a\tb\n");
	ctl_run("dcf check %s/bad.eds", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	snprintf(want, sizeof want,
		 "warning: %s/bad.eds:4: DefaultValue '256': out of range for UNSIGNED8 (max 255): "
		 "the value is not used\n"
		 "warning: %s/bad.eds:7: [2001]: SubNumber=3 but 2 sub-object sections [2001subN]: "
		 "the sections present are used\n"
		 "warning: %s/bad.eds:15: DefaultValue: control character in a VISIBLE_STRING (CiA "
		 "301: 20h..7Eh); the bytes are sent as they are\n"
		 "warning: 3 warnings in all\n",
		 dir, dir, dir);
	TEST_ASSERT_EQUAL_STRING(want, res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "ok: 2 objects, 3 values, 1 entries"),
				     res.out);
	ctl_run("--json dcf check %s/bad.eds", dir);
	TEST_ASSERT_EQUAL_INT(0, res.exit);
	o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	TEST_ASSERT_EQUAL_INT(3, cJSON_GetObjectItem(o, "warnings")->valueint);
	TEST_ASSERT_EQUAL_INT(3, cJSON_GetArraySize(cJSON_GetObjectItem(o, "warning_list")));
	TEST_ASSERT_NOT_NULL(
		strstr(cJSON_GetArrayItem(cJSON_GetObjectItem(o, "warning_list"), 1)->valuestring,
		       "bad.eds:7: [2001]: SubNumber=3"));
	cJSON_Delete(o);
	ctl_run("dcf check %s/bad.eds --strict", dir);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	snprintf(want, sizeof want,
		 "cogwctl dcf check: %s/bad.eds:4: DefaultValue '256': out of range for UNSIGNED8 "
		 "(max 255)\n",
		 dir);
	TEST_ASSERT_EQUAL_STRING(want, res.err);

	/* $NODEID without a node id: check evaluates it as 1 and says so, convert refuses */
	put("n.eds", "[1014]\nDataType=7\nAccessType=rw\nDefaultValue=$NODEID+0x80\n");
	ctl_run("dcf check %s/n.eds", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL(strstr(res.out, "note: $NODEID evaluated as 1"));
	ctl_run("dcf convert %s/n.eds -o %s/n.cdc", dir, dir);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(
		strstr(res.err, "n.eds:4: DefaultValue '$NODEID+0x80': $NODEID needs a node id"),
		res.err);
	char path[128];
	snprintf(path, sizeof path, "%s/n.cdc", dir);
	TEST_ASSERT_NOT_EQUAL(0, access(path, F_OK)); /* nothing written */
}

static void test_usage_errors(void)
{
	put("dev.dcf", dcf_text);
	ctl_run("dcf convert %s/dev.dcf --node 5", dir);
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	TEST_ASSERT_NOT_NULL(strstr(res.err, "-o FILE.cdc missing"));
	ctl_run("dcf convert %s/dev.dcf --node 128 -o x.cdc", dir);
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	ctl_run("dcf frobnicate %s/dev.dcf", dir);
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	ctl_run("dcf check");
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	ctl_run("dcf check %s/none.eds", dir);
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(
		strstr(res.err, "none.eds: cannot open: No such file or directory"), res.err);
	ctl_run("dcf --help");
	TEST_ASSERT_EQUAL_INT(0, res.exit);
	TEST_ASSERT_NOT_NULL(strstr(res.out, "usage: cogwctl dcf check FILE"));
	ctl_run("--help");
	TEST_ASSERT_NOT_NULL(strstr(res.out, "dcf convert FILE --node N -o OUT.cdc"));
}

/* A vendor's EDS from python-canopen's source distribution (fetched by
 * scripts/fetch-python-canopen.sh at set-up; the VM cannot fetch). */
static void test_vendor_eds(void)
{
	const char *env = getenv("COGW_PYCANOPEN_DIR");
	char eds[512];
	snprintf(eds, sizeof eds, "%s/examples/eds/e35.eds",
		 env ? env : "build/deps/python-canopen/canopen-2.4.1");
	if (access(eds, R_OK))
		TEST_IGNORE_MESSAGE(
			"python-canopen sdist not fetched (scripts/fetch-python-canopen.sh)");
	ctl_run("--json dcf convert %s --node 5 -o %s/e35.cdc", eds, dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	TEST_ASSERT_TRUE(cJSON_IsTrue(cJSON_GetObjectItem(o, "ok")));
	TEST_ASSERT_EQUAL_INT(658, cJSON_GetObjectItem(o, "entries")->valueint);
	TEST_ASSERT_EQUAL_INT(2, cJSON_GetObjectItem(o, "warnings")->valueint);
	TEST_ASSERT_EQUAL_INT(2, cJSON_GetArraySize(cJSON_GetObjectItem(o, "warning_list")));
	cJSON_Delete(o);
	ctl_run("dcf check %s/e35.cdc", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL(strstr(res.out, "concise DCF ok: 658 entries"));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_check_and_convert);
	RUN_TEST(test_refused_file_names_the_line);
	RUN_TEST(test_usage_errors);
	RUN_TEST(test_vendor_eds);
	return UNITY_END();
}
