/* apps/common/eds: CiA 306 EDS/DCF import to a concise DCF. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "apps/common/eds.h"
#include "core/cdcf.h"
#include "tests/unit/support/fetch.h"
#include "unity.h"

static char err[512];
static uint8_t *out;
static size_t out_len;
static eds_stats st;

/* A conversion's result into the globals the checks read. */
static int kept(int rc, const eds_result *res)
{
	out = res->cdcf;
	out_len = res->len;
	st = res->stats;
	snprintf(err, sizeof err, "%s", res->err);
	return rc;
}

void setUp(void)
{
	out = NULL;
	out_len = 0;
	err[0] = '\0';
}

void tearDown(void)
{
	free(out);
}

static int conv(const char *text, uint8_t node)
{
	free(out);
	out = NULL;
	eds_result res;

	return kept(eds_convert(text, strlen(text), "t.dcf", node, &res), &res);
}

static int conv_strict(const char *text, uint8_t node)
{
	eds_options o = { .node_id = node, .strict = true };
	eds_result res;

	free(out);
	out = NULL;
	return kept(eds_convert_opts(text, strlen(text), "t.dcf", &o, &res), &res);
}

#define HEAD "[FileInfo]\nFileName=t.dcf\n\n"

/* Strict reading (the rules before lenient reading) refuses the file
 * and the message is exactly `want`; lenient reading: test_lenient_reading. */
static void expect_err(const char *text, uint8_t node, const char *want)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, conv_strict(text, node), text);
	TEST_ASSERT_EQUAL_STRING(want, err);
	TEST_ASSERT_NULL(out);
}

typedef struct want_ent {
	uint16_t index;
	uint8_t sub;
	uint32_t size;
	uint64_t le; /* value, little-endian bytes */
} want_ent;

static void expect_entries(const want_ent *w, size_t n)
{
	co_cdcf_iter it;
	co_cdcf_entry e;
	char msg[64];
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, out, out_len, NULL));
	TEST_ASSERT_EQUAL_UINT32(n, it.count);
	for (size_t i = 0; i < n; i++) {
		TEST_ASSERT_TRUE(co_cdcf_iter_next(&it, &e));
		snprintf(msg, sizeof msg, "entry %zu (%04X:%02X)", i + 1, w[i].index, w[i].sub);
		TEST_ASSERT_EQUAL_HEX16_MESSAGE(w[i].index, e.index, msg);
		TEST_ASSERT_EQUAL_HEX8_MESSAGE(w[i].sub, e.sub, msg);
		TEST_ASSERT_EQUAL_UINT32_MESSAGE(w[i].size, e.size, msg);
		uint64_t v = 0;
		for (uint32_t b = 0; b < e.size && b < 8; b++)
			v |= (uint64_t)e.data[b] << (8 * b);
		TEST_ASSERT_EQUAL_HEX64_MESSAGE(w[i].le, v, msg);
	}
	TEST_ASSERT_EQUAL_UINT(n, st.entries);
}

static void test_parameter_value_preferred_over_default(void)
{
	const char *t = HEAD
		"[1017]\nParameterName=Producer heartbeat time\nObjectType=0x7\n"
		"DataType=0x0006\nAccessType=rw\nDefaultValue=500\nParameterValue=1000\n"
		"[1000]\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x191\n"
		"[2000]\nDataType=0x0005\nAccessType=rww\nDefaultValue=7\n"
		"[2001]\nDataType=0x0005\nAccessType=rw\nDefaultValue=7\nParameterValue=\n"
		"[2002]\nDataType=0x0005\nAccessType=rw\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 0), err);
	const want_ent w[] = { { 0x1017, 0, 2, 1000 }, { 0x2000, 0, 1, 7 }, { 0x2001, 0, 1, 7 } };
	expect_entries(w, 3);
	TEST_ASSERT_EQUAL_UINT(5, st.objects);
	TEST_ASSERT_EQUAL_UINT(1, st.skipped); /* 2002: writable, no value */
	TEST_ASSERT_EQUAL_UINT(4, st.values);
}

static void test_nodeid_expressions(void)
{
	static const char *forms[] = { "$NODEID+0x180", "0x180+$NODEID", "$nodeid + 384",
				       " 384+$NodeId", "$NODEID+0600" };
	char t[256];
	for (size_t i = 0; i < sizeof forms / sizeof forms[0]; i++) {
		snprintf(t, sizeof t,
			 HEAD "[2000]\nDataType=0x0007\nAccessType=rw\nDefaultValue=%s\n",
			 forms[i]);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 5), err);
		const want_ent w[] = { { 0x2000, 0, 4, 0x185 } };
		expect_entries(w, 1);
		TEST_ASSERT_EQUAL_UINT8(5, st.node_id);
	}
	/* node id from [DeviceComissioning] when none is given; an explicit one wins */
	const char *dc = HEAD
		"[DeviceComissioning]\nNodeID=0x10\n[2000]\nDataType=0x0007\nAccessType=rw\n"
		"DefaultValue=$NODEID\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(dc, 0), err);
	const want_ent w10[] = { { 0x2000, 0, 4, 0x10 } };
	expect_entries(w10, 1);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(dc, 3), err);
	const want_ent w3[] = { { 0x2000, 0, 4, 3 } };
	expect_entries(w3, 1);
}

static void test_bad_expressions(void)
{
	const char *pre = HEAD "[2000]\nDataType=0x0007\nAccessType=rw\nDefaultValue=";
	char t[256];
	struct {
		const char *v;
		const char *msg;
	} bad[] = {
		{ "$NODEID-1", "t.dcf:7: DefaultValue '$NODEID-1': bad expression (only $NODEID, "
			       "'+' and numbers)" },
		{ "$NODEID+$NODEID", "t.dcf:7: DefaultValue '$NODEID+$NODEID': $NODEID twice" },
		{ "1+2", "t.dcf:7: DefaultValue '1+2': bad expression (two numbers)" },
		{ "1+2+$NODEID", "t.dcf:7: DefaultValue '1+2+$NODEID': more than two terms" },
		{ "$NODE+1", "t.dcf:7: DefaultValue '$NODE+1': bad expression (only $NODEID, '+' "
			     "and numbers)" },
		{ "0x1G",
		  "t.dcf:7: DefaultValue '0x1G': not a number (decimal, 0x hex or 0 octal)" },
		{ "09", "t.dcf:7: DefaultValue '09': not a number (decimal, 0x hex or 0 octal)" },
		{ "0x", "t.dcf:7: DefaultValue '0x': not a number (decimal, 0x hex or 0 octal)" },
		{ "$NODEID+",
		  "t.dcf:7: DefaultValue '$NODEID+': not a number (decimal, 0x hex or 0 octal)" },
		{ "$NODEID+-4",
		  "t.dcf:7: DefaultValue '$NODEID+-4': $NODEID with a negative number" },
		{ "0x100000000", "t.dcf:7: DefaultValue '0x100000000': out of range for UNSIGNED32 "
				 "(max 4294967295)" },
		{ "99999999999999999999",
		  "t.dcf:7: DefaultValue '99999999999999999999': number too large" },
	};
	for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
		snprintf(t, sizeof t, "%s%s\n", pre, bad[i].v);
		expect_err(t, 1, bad[i].msg);
	}
	snprintf(t, sizeof t, "%s$NODEID+0x180\n", pre);
	expect_err(t, 0,
		   "t.dcf:7: DefaultValue '$NODEID+0x180': $NODEID needs a node id (none given and "
		   "no [DeviceComissioning] NodeID)");
	expect_err(HEAD "[DeviceComissioning]\nNodeID=128\n[2000]\nDataType=7\nAccessType=ro\n", 0,
		   "t.dcf:5: NodeID '128': out of range 0..127");
	expect_err(HEAD "[2000]\nDataType=7\nAccessType=ro\n", 200,
		   "t.dcf:0: node id 200 is out of range 1..127");
}

static void test_numbers_by_type(void)
{
	const char *t = HEAD
		"[2000]\nDataType=0x0005\nAccessType=rw\nDefaultValue=010\n"    /* octal 8 */
		"[2001]\nDataType=0x0003\nAccessType=rw\nDefaultValue=-2\n"     /* INTEGER16 */
		"[2002]\nDataType=0x0003\nAccessType=rw\nDefaultValue=0xFFFE\n" /* bit pattern -2 */
		"[2003]\nDataType=0x0001\nAccessType=rw\nDefaultValue=1\n"      /* BOOLEAN */
		"[2004]\nDataType=0x0008\nAccessType=rw\nDefaultValue=1.5\n"    /* REAL32 */
		"[2005]\nDataType=0x0011\nAccessType=rw\nDefaultValue=0x3FF0000000000000\n" /* REAL64 1.0 */
		"[2006]\nDataType=0x0010\nAccessType=rw\nDefaultValue=-8388608\n" /* INTEGER24 min */
		"[2007]\nDataType=0x001B\nAccessType=rw\nDefaultValue=0xFFFFFFFFFFFFFFFF\n"
		"[2008]\nDataType=0x0015\nAccessType=rw\nDefaultValue=-9223372036854775808\n"
		"[2009]\nDataType=0x0016\nAccessType=rw\nDefaultValue=0xABCDEF\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 1), err);
	const want_ent w[] = {
		{ 0x2000, 0, 1, 8 },
		{ 0x2001, 0, 2, 0xFFFE },
		{ 0x2002, 0, 2, 0xFFFE },
		{ 0x2003, 0, 1, 1 },
		{ 0x2004, 0, 4, 0x3FC00000 },
		{ 0x2005, 0, 8, 0x3FF0000000000000 },
		{ 0x2006, 0, 3, 0x800000 },
		{ 0x2007, 0, 8, UINT64_MAX },
		{ 0x2008, 0, 8, 0x8000000000000000 },
		{ 0x2009, 0, 3, 0xABCDEF },
	};
	expect_entries(w, sizeof w / sizeof w[0]);
}

static void test_wrong_values_for_types(void)
{
	char t[256];
	struct {
		const char *type, *v, *msg;
	} bad[] = {
		{ "0x0005", "256",
		  "t.dcf:7: DefaultValue '256': out of range for UNSIGNED8 (max 255)" },
		{ "0x0005", "-1", "t.dcf:7: DefaultValue '-1': negative value for UNSIGNED8" },
		{ "0x0003", "40000", "t.dcf:7: DefaultValue '40000': out of range for INTEGER16" },
		{ "0x0003", "-32769",
		  "t.dcf:7: DefaultValue '-32769': out of range for INTEGER16" },
		{ "0x0003", "0x10000",
		  "t.dcf:7: DefaultValue '0x10000': out of range for INTEGER16" },
		{ "0x0001", "2", "t.dcf:7: DefaultValue '2': out of range for BOOLEAN (max 1)" },
		{ "0x0008", "abc", "t.dcf:7: DefaultValue 'abc': not a number for REAL32" },
		{ "0x0008", "1e39", "t.dcf:7: DefaultValue '1e39': out of range for REAL32" },
		{ "0x0008", "0x100000000",
		  "t.dcf:7: DefaultValue '0x100000000': REAL32 bit pattern wider than 32 bits" },
		{ "0x000A", "0102F", "t.dcf:7: DefaultValue '0102F': odd number of hex digits" },
		{ "0x000A", "01 0Z",
		  "t.dcf:7: DefaultValue '01 0Z': OCTET_STRING value must be hex digits" },
		{ "0x000C", "5",
		  "t.dcf:7: DefaultValue: values of TIME_OF_DAY are not supported in EDS/DCF "
		  "files" },
		{ "0x0040", "5", "t.dcf:5: DataType 0x0040 is not a CiA 301 basic data type" },
		{ "0x10000", "5", "t.dcf:5: DataType '0x10000': out of range 0..65535" },
	};
	for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
		snprintf(t, sizeof t, HEAD "[2000]\nDataType=%s\nAccessType=rw\nDefaultValue=%s\n",
			 bad[i].type, bad[i].v);
		expect_err(t, 1, bad[i].msg);
	}
	/* read-only values are checked too: a broken value is a broken file */
	expect_err(HEAD "[2000]\nDataType=5\nAccessType=ro\nDefaultValue=300\n", 1,
		   "t.dcf:7: DefaultValue '300': out of range for UNSIGNED8 (max 255)");
	expect_err(HEAD "[2000]\nDataType=5\nAccessType=rx\n", 1,
		   "t.dcf:6: AccessType 'rx': not one of ro, wo, rw, rwr, rww, const");
	expect_err(HEAD "[2000]\nAccessType=rw\n", 1, "t.dcf:4: [2000]: DataType missing");
	expect_err(HEAD "[2000]\nDataType=5\n", 1, "t.dcf:4: [2000]: AccessType missing");
	expect_err(HEAD "[2000]\nObjectType=0x3\nDataType=5\nAccessType=rw\n", 1,
		   "t.dcf:5: ObjectType '0x3' is not one of 0x2 (DOMAIN), 0x5 (DEFTYPE), 0x6 "
		   "(DEFSTRUCT), 0x7 (VAR), 0x8 (ARRAY), 0x9 (RECORD)");
}

static void test_strings_and_domains(void)
{
	const char *t = HEAD "[2000]\nDataType=0x0009\nAccessType=rw\nDefaultValue=pump 3\n"
			     "[2001]\nDataType=0x000A\nAccessType=rw\nDefaultValue=01 02 0a\n"
			     "[2002]\nDataType=0x000B\nAccessType=rw\nDefaultValue=\xC3\xA9!\n"
			     "[2003]\nObjectType=0x2\nAccessType=rw\nDefaultValue=DEADBEEF\n"
			     "[2004]\nDataType=0x0009\nAccessType=rw\nDefaultValue=\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 1), err);
	const want_ent w[] = {
		{ 0x2000, 0, 6, 0x3320706D7570 }, /* "pump 3" */
		{ 0x2001, 0, 3, 0x0A0201 },
		{ 0x2002, 0, 4, 0x002100E9 }, /* UTF-16LE */
		{ 0x2003, 0, 4, 0xEFBEADDE },
	};
	expect_entries(w, 4);
	expect_err(HEAD "[2000]\nDataType=0x000B\nAccessType=rw\nDefaultValue=\xC3\n", 1,
		   "t.dcf:7: DefaultValue: UNICODE_STRING is not valid UTF-8");
	expect_err(HEAD "[2000]\nDataType=0x0009\nAccessType=rw\nDefaultValue=a\tb\n", 1,
		   "t.dcf:7: DefaultValue: control character in a VISIBLE_STRING");
}

static void test_ini_syntax_errors(void)
{
	expect_err(HEAD "[1017]\nDataType=6\nAccessType=rw\n[1017]\nDataType=6\nAccessType=rw\n", 1,
		   "t.dcf:7: duplicate section [1017] (first at line 4)");
	expect_err(HEAD "[1018]\nObjectType=9\nSubNumber=1\n[1018sub1]\nDataType=7\nAccessType=ro\n"
			"[1018SUB01]\nDataType=7\nAccessType=ro\n",
		   1, "t.dcf:10: duplicate section [1018SUB01] (first at line 7)");
	expect_err(HEAD "[comments]\n[Comments]\n", 1,
		   "t.dcf:5: duplicate section [Comments] (first at line 4)");
	expect_err(HEAD "[2000]\nDataType=5\naccesstype=rw\nAccessType=ro\n", 1,
		   "t.dcf:7: duplicate key 'AccessType' in [2000] (first at line 6)");
	expect_err("DataType=5\n[2000]\n", 1, "t.dcf:1: key=value before the first [section]");
	expect_err(HEAD "[2000\n", 1, "t.dcf:4: section header without closing ']'");
	expect_err(HEAD "[ ]\n", 1, "t.dcf:4: empty section name");
	expect_err(HEAD "[2000]\nthis is no key\n", 1,
		   "t.dcf:5: expected [section] or key=value, got 'this is no key'");
	expect_err(HEAD "[2000]\n=5\n", 1, "t.dcf:5: no key before '='");
	expect_err(HEAD "[2000sub100]\n", 1,
		   "t.dcf:4: [2000sub100]: sub-index must be 1 or 2 hex digits (00..FF)");
	expect_err(HEAD "[DeviceInfo]\nVendorName=x\n", 1,
		   "t.dcf:0: no object sections: not an EDS or DCF");
	static const char nul[] = "[2000]\nDataType=5\0\nAccessType=rw\n";
	eds_result res;
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      kept(eds_convert(nul, sizeof nul - 1, "t.dcf", 1, &res), &res));
	TEST_ASSERT_EQUAL_STRING("t.dcf:2: NUL byte: not a text file", err);
	/* CRLF, comments, blanks and case-insensitive keys are fine */
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0,
		conv("; comment\r\n[2000]\r\n  datatype = 0x5 \r\n# x\r\nACCESSTYPE=RW\r\n"
		     "defaultvalue=3\r\n",
		     1),
		err);
	const want_ent w[] = { { 0x2000, 0, 1, 3 } };
	expect_entries(w, 1);
}

static void test_sub_objects(void)
{
	const char *t = HEAD
		"[1016]\nObjectType=0x8\nSubNumber=3\n"
		"[1016sub0]\nDataType=5\nAccessType=ro\nDefaultValue=2\n"
		"[1016sub1]\nDataType=7\nAccessType=rw\nDefaultValue=0x000503E8\n"
		"[1016sub2]\nDataType=7\nAccessType=rw\nParameterValue=$NODEID+0x10000\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 7), err);
	const want_ent w[] = { { 0x1016, 1, 4, 0x503E8 }, { 0x1016, 2, 4, 0x10007 } };
	expect_entries(w, 2);

	expect_err(HEAD
		   "[1016]\nObjectType=0x8\nSubNumber=3\n[1016sub0]\nDataType=5\nAccessType=ro\n"
		   "[1016sub2]\nDataType=7\nAccessType=rw\n",
		   1, "t.dcf:6: [1016]: SubNumber=3 but 2 sub-object sections [1016subN]");
	expect_err(HEAD
		   "[1016]\nObjectType=0x8\nSubNumber=1\n[1016sub1]\nDataType=7\nAccessType=rw\n",
		   1, "t.dcf:4: [1016]: no sub-object section [1016sub0]");
	expect_err(HEAD "[1016]\nObjectType=0x8\n", 1,
		   "t.dcf:4: [1016]: ARRAY without SubNumber or CompactSubObj");
	expect_err(HEAD
		   "[2000]\nDataType=5\nAccessType=rw\n[2001sub0]\nDataType=5\nAccessType=ro\n",
		   1, "t.dcf:7: [2001sub0] without object [2001]");
	expect_err(HEAD
		   "[2000]\nDataType=5\nAccessType=rw\n[2000sub0]\nDataType=5\nAccessType=ro\n",
		   1, "t.dcf:7: [2000sub0]: sub-object of VAR object [2000]");
	expect_err(HEAD "[2000]\nObjectType=9\nSubNumber=1\n[2000sub0]\nObjectType=8\nDataType="
			"5\nAccessType=ro\n",
		   1, "t.dcf:8: [2000sub0]: a sub-object must have ObjectType 0x7 (VAR)");
}

static void test_compact_sub_objects(void)
{
	const char *t = HEAD
		"[2100]\nObjectType=0x8\nCompactSubObj=3\nDataType=0x0006\nAccessType=rw\n"
		"DefaultValue=7\n"
		"[2100Name]\nNrOfEntries=3\n1=a\n2=b\n3=c\n"
		"[2100Value]\nNrOfEntries=1\n2=$NODEID+9\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 1), err);
	const want_ent w[] = { { 0x2100, 1, 2, 7 }, { 0x2100, 2, 2, 10 }, { 0x2100, 3, 2, 7 } };
	expect_entries(w, 3);

	expect_err(HEAD "[2100]\nObjectType=0x8\nCompactSubObj=2\nDataType=6\nAccessType=rw\n"
			"[2100Name]\nNrOfEntries=3\n1=a\n4=d\n",
		   1, "t.dcf:12: [2100Name]: sub-index 4 beyond CompactSubObj=2");
	expect_err(HEAD "[2100]\nObjectType=0x8\nCompactSubObj=2\nDataType=6\nAccessType=rw\n"
			"[2100Name]\nNrOfEntries=3\n1=a\n2=d\n",
		   1, "t.dcf:10: [2100Name]: NrOfEntries=3 but 2 entries");
	expect_err(HEAD "[2100]\nObjectType=0x9\nCompactSubObj=2\nDataType=6\nAccessType=rw\n", 1,
		   "t.dcf:6: [2100]: CompactSubObj on a RECORD (only ARRAY)");
	expect_err(HEAD "[2100]\nObjectType=0x8\nCompactSubObj=0\nDataType=6\nAccessType=rw\n", 1,
		   "t.dcf:6: CompactSubObj must be 1..254");
	expect_err(HEAD
		   "[2100]\nObjectType=0x8\nSubNumber=1\n[2100sub0]\nDataType=5\nAccessType=ro\n"
		   "[2100Value]\nNrOfEntries=0\n",
		   1, "t.dcf:10: [2100Value] but [2100] has no CompactSubObj");
	expect_err(HEAD "[2100]\nObjectType=0x8\nCompactSubObj=2\nDataType=6\nAccessType=rw\n"
			"[2100Value]\nNrOfEntries=1\n1=70000\n",
		   1, "t.dcf:11: 1 '70000': out of range for UNSIGNED16 (max 65535)");
}

static void test_object_links_and_lists(void)
{
	const char *ok = HEAD
		"[OptionalObjects]\nSupportedObjects=2\n1=0x2000\n2=0x2001\n"
		"[2000]\nDataType=5\nAccessType=rw\n[2001]\nDataType=5\nAccessType=rw\n"
		"[2000ObjectLinks]\nObjectLinks=1\n1=0x2001\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(ok, 1), err);
	TEST_ASSERT_EQUAL_UINT(0, st.warnings);

	expect_err(
		HEAD
		"[2000]\nDataType=5\nAccessType=rw\n[2000ObjectLinks]\nObjectLinks=1\n1=0x2001\n",
		1, "t.dcf:9: [2000ObjectLinks]: linked object 0x2001 has no section");
	expect_err(
		HEAD
		"[2000]\nDataType=5\nAccessType=rw\n[2000ObjectLinks]\nObjectLinks=1\n2=0x2000\n",
		1, "t.dcf:9: [2000ObjectLinks]: entry 2 beyond ObjectLinks=1");
	expect_err(HEAD "[2000]\nDataType=5\nAccessType=rw\n[2001ObjectLinks]\nObjectLinks=0\n", 1,
		   "t.dcf:7: [2001ObjectLinks] without object [2001]");

	/* a listed object without a section, and a wrong count: warnings only */
	const char *w = HEAD "[OptionalObjects]\nSupportedObjects=3\n1=0x2000\n2=0x6505\n"
			     "[2000]\nDataType=5\nAccessType=rw\nDefaultValue=1\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(w, 1), err);
	TEST_ASSERT_EQUAL_UINT(2, st.warnings);
	TEST_ASSERT_EQUAL_STRING("t.dcf:5: [OptionalObjects]: SupportedObjects=3 but 2 entries",
				 st.first_warning);
	expect_err(HEAD "[OptionalObjects]\n1=0x2000\n[2000]\nDataType=5\nAccessType=rw\n", 1,
		   "t.dcf:4: [OptionalObjects]: SupportedObjects missing");
	expect_err(HEAD "[OptionalObjects]\nSupportedObjects=1\n1=0x2000x\n[2000]\nDataType="
			"5\nAccessType=rw\n",
		   1, "t.dcf:6: 1 '0x2000x': not a number (decimal, 0x hex or 0 octal)");
}

static void test_limits(void)
{
	expect_err(HEAD
		   "[2000]\nDataType=3\nAccessType=rw\nLowLimit=-5\nHighLimit=5\nDefaultValue=-6\n",
		   1, "t.dcf:9: DefaultValue '-6' is below LowLimit '-5' (line 7)");
	expect_err(
		HEAD
		"[2000]\nDataType=3\nAccessType=rw\nLowLimit=-5\nHighLimit=0x7\nDefaultValue=8\n",
		1, "t.dcf:9: DefaultValue '8' is above HighLimit '0x7' (line 8)");
	expect_err(HEAD
		   "[2000]\nDataType=5\nAccessType=rw\nLowLimit=3\nHighLimit=1\nDefaultValue=2\n",
		   1, "t.dcf:8: HighLimit '1' is below LowLimit '3' (line 7)");
	/* signed limits given as bit patterns (0xFFFFFFFF = -1) */
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0,
		conv(HEAD "[2000]\nDataType=4\nAccessType=rw\nLowLimit=0x80000000\n"
			  "HighLimit=0xFFFFFFFF\nDefaultValue=-3\n",
		     1),
		err);
	expect_err(HEAD
		   "[2000]\nDataType=4\nAccessType=rw\nLowLimit=0x80000000\nHighLimit=0xFFFFFFFF\n"
		   "DefaultValue=0\n",
		   1, "t.dcf:9: DefaultValue '0' is above HighLimit '0xFFFFFFFF' (line 8)");
}

static void test_commands_and_read_only_not_written(void)
{
	const char *t = HEAD
		"[1010]\nObjectType=8\nSubNumber=2\n[1010sub0]\nDataType=5\nAccessType=ro\n"
		"DefaultValue=1\n[1010sub1]\nDataType=7\nAccessType=rw\nDefaultValue=1\n"
		"[1003]\nObjectType=8\nSubNumber=1\n[1003sub0]\nDataType=5\nAccessType="
		"rw\nDefaultValue=0\n"
		"[1008]\nDataType=9\nAccessType=const\nDefaultValue=dev\n"
		"[1005]\nDataType=7\nAccessType=rw\nDefaultValue=0x80\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 1), err);
	const want_ent w[] = { { 0x1005, 0, 4, 0x80 } };
	expect_entries(w, 1);
}

static void test_pdo_remapping_order(void)
{
	const char *t = HEAD "[1800]\nObjectType=9\nSubNumber=4\n"
			     "[1800sub0]\nDataType=5\nAccessType=const\nDefaultValue=5\n"
			     "[1800sub1]\nDataType=7\nAccessType=rw\nDefaultValue=$NODEID+0x180\n"
			     "[1800sub2]\nDataType=5\nAccessType=rw\nDefaultValue=255\n"
			     "[1800sub5]\nDataType=6\nAccessType=rw\nDefaultValue=100\n"
			     "[1A00]\nObjectType=9\nSubNumber=4\n"
			     "[1A00sub0]\nDataType=5\nAccessType=rw\nDefaultValue=2\n"
			     "[1A00sub1]\nDataType=7\nAccessType=rw\nDefaultValue=0x60000108\n"
			     "[1A00sub2]\nDataType=7\nAccessType=rw\nDefaultValue=0x60000210\n"
			     "[1A00sub3]\nDataType=7\nAccessType=rw\nDefaultValue=0\n"
			     /* mapping without a writable comm. record: mapping steps only */
			     "[1601]\nObjectType=9\nSubNumber=2\n"
			     "[1601sub0]\nDataType=5\nAccessType=rw\nDefaultValue=1\n"
			     "[1601sub1]\nDataType=7\nAccessType=rw\nDefaultValue=0x62000108\n"
			     /* a disabled PDO stays disabled: no final COB-ID write */
			     "[1401]\nObjectType=9\nSubNumber=2\n"
			     "[1401sub0]\nDataType=5\nAccessType=const\nDefaultValue=2\n"
			     "[1401sub1]\nDataType=7\nAccessType=rw\nDefaultValue=0x80000300\n"
			     "[2000]\nDataType=5\nAccessType=rw\nDefaultValue=1\n";
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, conv(t, 4), err);
	const want_ent w[] = {
		{ 0x1401, 1, 4, 0x80000300 }, { 0x1601, 0, 1, 0 },
		{ 0x1601, 1, 4, 0x62000108 }, { 0x1601, 0, 1, 1 },
		{ 0x1800, 1, 4, 0x80000184 }, { 0x1800, 2, 1, 255 },
		{ 0x1800, 5, 2, 100 },        { 0x1A00, 0, 1, 0 },
		{ 0x1A00, 1, 4, 0x60000108 }, { 0x1A00, 2, 4, 0x60000210 },
		{ 0x1A00, 0, 1, 2 },          { 0x1800, 1, 4, 0x184 },
		{ 0x2000, 0, 1, 1 },
	};
	expect_entries(w, sizeof w / sizeof w[0]);

	expect_err(HEAD "[1A00]\nObjectType=9\nSubNumber=2\n[1A00sub0]\nDataType=5\nAccessType="
			"rw\nDefaultValue=2\n"
			"[1A00sub1]\nDataType=7\nAccessType=rw\nDefaultValue=0x60000108\n",
		   1, "t.dcf:10: PDO mapping 1A00h: sub0=2 but sub 2 has no writable value");
	expect_err(HEAD "[1A00]\nObjectType=9\nSubNumber=1\n[1A00sub0]\nDataType=5\nAccessType="
			"rw\nDefaultValue=65\n",
		   1, "t.dcf:10: PDO mapping 1A00h: sub0=65, at most 64 entries");
}

/* ---- lenient reading: warnings with file:line, the file is used ---- */

static char warned[16][300];
static unsigned n_warned;

static void record_warning(void *arg, const char *text)
{
	(void)arg;
	if (n_warned < 16)
		snprintf(warned[n_warned], sizeof warned[0], "%s", text);
	n_warned++;
}

/* Read leniently, with the warning callback: accepted, with exactly the
 * warnings `want` (in order), and strict reading refuses it with the
 * first of them (without what lenient reading adds after ':' or '('). */
static void expect_warnings(const char *text, uint8_t node, const char *const *want, unsigned n,
			    const char *strict_err)
{
	eds_options o = { .node_id = node, .on_warning = record_warning };
	eds_result res;

	free(out);
	out = NULL;
	n_warned = 0;
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0, kept(eds_convert_opts(text, strlen(text), "t.dcf", &o, &res), &res), err);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(n, n_warned, n_warned ? warned[0] : text);
	TEST_ASSERT_EQUAL_UINT(n, st.warnings);
	for (unsigned i = 0; i < n && i < 16; i++)
		TEST_ASSERT_EQUAL_STRING(want[i], warned[i]);
	if (n)
		TEST_ASSERT_EQUAL_STRING(want[0], st.first_warning);
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_check(out, out_len, NULL, NULL));
	if (strict_err) {
		uint8_t *keep = out;
		size_t keep_len = out_len;
		eds_stats keep_st = st;
		out = NULL;
		TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, conv_strict(text, node), text);
		TEST_ASSERT_EQUAL_STRING(strict_err, err);
		out = keep;
		out_len = keep_len;
		st = keep_st;
	}
}

/* Refused also when read leniently (and strictly). */
static void expect_refused(const char *text, uint8_t node, const char *want)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, conv(text, node), text);
	TEST_ASSERT_EQUAL_STRING(want, err);
	TEST_ASSERT_NULL(out);
	expect_err(text, node, want);
}

static void test_lenient_visible_string(void)
{
	/* the CANopenNode editor writes tabs and UTF-8 into VISIBLE_STRING
	 * defaults: the bytes are sent as they are */
	const char *t = HEAD "[2121]\nObjectType=0x9\nSubNumber=0x2\n"
			     "[2121sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=0x01\n"
			     "[2121sub1]\nDataType=0x0009\nAccessType=rw\n"
			     "DefaultValue=up\t\xE2\x82\xAC\n";
	const char *w[] = { "t.dcf:14: DefaultValue: control character in a VISIBLE_STRING "
			    "(CiA 301: 20h..7Eh); the bytes are sent as they are" };
	expect_warnings(t, 1, w, 1,
			"t.dcf:14: DefaultValue: control character in a VISIBLE_STRING");
	const want_ent e[] = { { 0x2121, 1, 6, 0xAC82E2097075 } };
	expect_entries(e, 1);
	const char *u[] = { "t.dcf:7: DefaultValue: non-ASCII text in a VISIBLE_STRING (CiA 301: "
			    "20h..7Eh); the bytes are sent as they are" };
	expect_warnings(HEAD "[2000]\nDataType=0x0009\nAccessType=rw\nDefaultValue=5 \xC2\xB5s\n",
			1, u, 1, NULL); /* strict reading took UTF-8 as it is, too */
}

static void test_lenient_sub_numbers(void)
{
	/* python-canopen reads the sub-object sections present, whatever
	 * SubNumber says; so do we */
	const char *t = HEAD "[1016]\nObjectType=0x8\nSubNumber=3\n"
			     "[1016sub0]\nDataType=5\nAccessType=ro\nDefaultValue=2\n"
			     "[1016sub2]\nDataType=7\nAccessType=rw\nDefaultValue=0x000501F4\n"
			     "[1018]\nObjectType=0x9\n"
			     "[1018sub1]\nDataType=7\nAccessType=rw\nDefaultValue=9\n";
	const char *w[] = {
		"t.dcf:6: [1016]: SubNumber=3 but 2 sub-object sections [1016subN]: the sections "
		"present are used",
		"t.dcf:15: [1018]: RECORD without SubNumber or CompactSubObj",
		"t.dcf:15: [1018]: no sub-object section [1018sub0]",
	};
	expect_warnings(t, 1, w, 3,
			"t.dcf:6: [1016]: SubNumber=3 but 2 sub-object sections [1016subN]");
	const want_ent e[] = { { 0x1016, 2, 4, 0x000501F4 }, { 0x1018, 1, 4, 9 } };
	expect_entries(e, 2);

	/* sub-objects of a VAR, SubNumber on a VAR: ignored, as python-canopen does */
	const char *v[] = { "t.dcf:8: [2000sub1]: sub-object of VAR object [2000] (ignored)" };
	expect_warnings(HEAD "[2000]\nDataType=5\nAccessType=rw\nDefaultValue=3\n"
			     "[2000sub1]\nDataType=5\nAccessType=rw\nDefaultValue=4\n",
			1, v, 1, "t.dcf:8: [2000sub1]: sub-object of VAR object [2000]");
	const want_ent e2[] = { { 0x2000, 0, 1, 3 } };
	expect_entries(e2, 1);

	/* CompactSubObj=255: sub-index FFh is not an element (CiA 301) */
	const char *c[] = { "t.dcf:6: [1003]: CompactSubObj=255, but sub-index FFh is reserved "
			    "(CiA 301): sub-objects 1..254 are used" };
	expect_warnings(HEAD
			"[1003]\nObjectType=0x8\nCompactSubObj=255\nDataType=7\nAccessType=ro\n",
			1, c, 1,
			"t.dcf:6: [1003]: CompactSubObj=255, but sub-index FFh is reserved "
			"(CiA 301)");
}

static void test_lenient_values(void)
{
	/* a default value that cannot be used is left out (python-canopen
	 * leaves it out too); the device keeps its own default */
	const char *t = HEAD "[2000]\nDataType=0x0004\nAccessType=rw\nDefaultValue=2147483648\n"
			     "[2001]\nDataType=0x000A\nAccessType=rw\nDefaultValue=0\n"
			     "[2002]\nDataType=0x0006\nAccessType=rw\nLowLimit=10\nHighLimit=20\n"
			     "DefaultValue=5\n"
			     "[2003]\nDataType=0x0006\nAccessType=rw\nLowLimit=x\nDefaultValue=5\n"
			     "[2004]\nDataType=0x0007\nAccessType=ro\nParameterValue=-1\n"
			     "[2005]\nDataType=0x0006\nAccessType=rw\nDefaultValue=7\n";
	const char *w[] = {
		"t.dcf:7: DefaultValue '2147483648': out of range for INTEGER32: the value is not "
		"used",
		"t.dcf:11: DefaultValue '0': odd number of hex digits: the value is not used",
		"t.dcf:17: DefaultValue '5' is below LowLimit '10' (line 15): the value is not "
		"used",
		"t.dcf:21: LowLimit 'x': not a number (decimal, 0x hex or 0 octal): the limit is "
		"not checked",
		"t.dcf:26: ParameterValue '-1': negative value for UNSIGNED32: the value is not "
		"used",
	};
	expect_warnings(t, 1, w, 5,
			"t.dcf:7: DefaultValue '2147483648': out of range for INTEGER32");
	const want_ent e[] = { { 0x2003, 0, 2, 5 }, { 0x2005, 0, 2, 7 } };
	expect_entries(e, 2);
	TEST_ASSERT_EQUAL_UINT(3, st.skipped);

	/* $NODEID with no node id is a missing input, not a fault of the file */
	expect_refused(HEAD "[2000]\nDataType=0x0007\nAccessType=ro\nDefaultValue=$NODEID+0x180\n",
		       0,
		       "t.dcf:7: DefaultValue '$NODEID+0x180': $NODEID needs a node id (none given "
		       "and no [DeviceComissioning] NodeID)");

	/* a DCF's configured value of a written entry cannot be left out */
	expect_refused(HEAD "[2000]\nDataType=0x0004\nAccessType=rw\nDefaultValue=0\n"
			    "ParameterValue=2147483648\n",
		       1, "t.dcf:8: ParameterValue '2147483648': out of range for INTEGER32");
	expect_refused(HEAD "[2100]\nObjectType=0x8\nCompactSubObj=2\nDataType=5\nAccessType=rw\n"
			    "[2100Value]\nNrOfEntries=1\n2=300\n",
		       1, "t.dcf:11: 2 '300': out of range for UNSIGNED8 (max 255)");
}

static void test_lenient_types_and_objects(void)
{
	/* structured or unknown types, no AccessType, unknown ObjectType:
	 * the entry is not used unless it carries a configured value */
	const char *t = HEAD "[2000]\nDataType=0x0020\nAccessType=rw\nDefaultValue=\n"
			     "[2001]\nDataType=0x0005\nDefaultValue=1\n"
			     "[2002]\nObjectType=0x3\nDataType=5\nAccessType=rw\nDefaultValue=1\n"
			     "[2003]\nObjectType=\nDataType=5\nAccessType=rw\nDefaultValue=2\n";
	const char *w[] = {
		"t.dcf:5: DataType 0x0020 is not a CiA 301 basic data type: the entry is not used",
		"t.dcf:8: [2001]: AccessType missing: the entry is not used",
		"t.dcf:12: ObjectType '0x3' is not one of 0x2 (DOMAIN), 0x5 (DEFTYPE), 0x6 "
		"(DEFSTRUCT), 0x7 (VAR), 0x8 (ARRAY), 0x9 (RECORD): the object is not used",
	};
	expect_warnings(t, 1, w, 3, "t.dcf:5: DataType 0x0020 is not a CiA 301 basic data type");
	const want_ent e[] = { { 0x2003, 0, 1, 2 } };
	expect_entries(e, 1);
	expect_refused(HEAD "[2000]\nDataType=0x0020\nAccessType=rw\nParameterValue=1\n", 1,
		       "t.dcf:5: DataType 0x0020 is not a CiA 301 basic data type");
	/* a sub-object without its object: no object type (python-canopen
	 * refuses it too) */
	expect_refused(HEAD "[1200sub1]\nDataType=7\nAccessType=ro\n", 1,
		       "t.dcf:4: [1200sub1] without object [1200]");
	/* configured compact values without CompactSubObj: nowhere to go */
	expect_refused(HEAD "[2000]\nDataType=5\nAccessType=rw\n[2000Value]\nNrOfEntries=1\n1=2\n",
		       1, "t.dcf:7: [2000Value] but [2000] has no CompactSubObj");
}

static void test_lenient_syntax(void)
{
	/* BOM, CRLF, inline comments after white space, trailing blanks:
	 * what Windows tools and hand-edited files carry, taken silently */
	const char *t = "\xEF\xBB\xBF[FileInfo] ; generated\r\nFileName=t.eds\r\n"
			"[2000]\r\nDataType=0x0006 ; UNSIGNED16\r\nAccessType=rw \t\r\n"
			"DefaultValue=0x10\t; sixteen\r\n"
			"[2001]\r\nDataType=9\r\nAccessType=rw\r\nDefaultValue=a;b\r\n";
	expect_warnings(t, 1, NULL, 0,
			"t.dcf:1: expected [section] or key=value, got '\xEF\xBB\xBF"
			"[FileInfo] ; generated'");
	const want_ent e[] = { { 0x2000, 0, 2, 0x10 }, { 0x2001, 0, 3, 0x623B61 } };
	expect_entries(e, 2);
	/* NodeID=0 ("not commissioned") is not used */
	const char *n[] = { "t.dcf:5: NodeID must be 1..127: NodeID is not used" };
	expect_warnings(HEAD "[DeviceComissioning]\nNodeID=0\n[2000]\nDataType=5\nAccessType=rw\n"
			     "DefaultValue=1\n",
			0, n, 1, "t.dcf:5: NodeID must be 1..127");
	/* object links and lists only describe: warnings in both readings */
	const char *l[] = { "t.dcf:9: [2000ObjectLinks]: linked object 0x2001 has no section" };
	expect_warnings(HEAD "[2000]\nDataType=5\nAccessType=rw\n[2000ObjectLinks]\nObjectLinks=1\n"
			     "1=0x2001\n",
			1, l, 1, "t.dcf:9: [2000ObjectLinks]: linked object 0x2001 has no section");
}

static void test_file_loader(void)
{
	char path[] = "/tmp/test_eds_XXXXXX";
	int fd = mkstemp(path);
	const char *t = "[2000]\nDataType=5\nAccessType=rw\nDefaultValue=9\n";
	eds_result res;
	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL_INT((int)strlen(t), (int)write(fd, t, strlen(t)));
	close(fd);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, kept(eds_convert_file(path, 1, &res), &res), err);
	TEST_ASSERT_EQUAL_UINT(1, st.entries);
	unlink(path);
	free(out);
	out = NULL;
	TEST_ASSERT_EQUAL_INT(-ENOENT, kept(eds_convert_file(path, 1, &res), &res));
	char want[128];
	snprintf(want, sizeof want, "%s: cannot open: No such file or directory", path);
	TEST_ASSERT_EQUAL_STRING(want, err);
	TEST_ASSERT_EQUAL_INT(-EIO, kept(eds_convert_file("/tmp", 1, &res), &res));
}

/* ---- files this project did not write (python-canopen's sdist, PyPI) ---- */

static const char *foreign_dir(void)
{
	static char dir[1024];
	const char *env = getenv("COGW_PYCANOPEN_DIR");

	return env ? env : fetch_deps_dir("scripts/fetch-python-canopen.sh", dir, sizeof dir);
}

static void test_foreign_eds_files(void)
{
	const char *dir = foreign_dir();
	char path[1200];
	eds_result res;
	TEST_ASSERT_NOT_NULL_MESSAGE(
		dir, "python-canopen sdist missing: scripts/fetch-python-canopen.sh failed");

	/* a vendor's device file: converts, with its DCF values and PDO order */
	snprintf(path, sizeof path, "%s/examples/eds/e35.eds", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, kept(eds_convert_file(path, 5, &res), &res), err);
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_check(out, out_len, NULL, NULL));
	TEST_ASSERT_TRUE(st.objects > 200);
	TEST_ASSERT_TRUE(st.entries > 500);
	/* it lists 0x6505 without describing it, and [ManufacturerObjects] says
	 * 105 objects but lists 104: warnings, nothing lost */
	TEST_ASSERT_EQUAL_UINT(2, st.warnings);
	TEST_ASSERT_NOT_NULL(
		strstr(st.first_warning, "object 0x6505 listed but no section [6505]"));
	co_cdcf_iter it;
	co_cdcf_entry e;
	unsigned seen_1400 = 0;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, out, out_len, NULL));
	while (co_cdcf_iter_next(&it, &e)) {
		if (e.index == 0x1400 && e.sub == 1) {
			/* ParameterValue=0x220 (not DefaultValue=$NODEID+0x200): disabled first, then set */
			uint32_t v = (uint32_t)e.data[0] | (uint32_t)e.data[1] << 8 |
				     (uint32_t)e.data[2] << 16 | (uint32_t)e.data[3] << 24;
			TEST_ASSERT_EQUAL_HEX32(seen_1400++ ? 0x220 : 0x80000220, v);
		}
	}
	TEST_ASSERT_EQUAL_UINT(2, seen_1400);
	free(out);
	out = NULL;

	/* the library's own test file has deliberate gaps: python-canopen
	 * reads the sections present, and so do we, with a warning each;
	 * strict reading refuses it with the line */
	snprintf(path, sizeof path, "%s/test/sample.eds", dir);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, kept(eds_convert_file(path, 5, &res), &res), err);
	TEST_ASSERT_EQUAL_UINT(6, st.warnings);
	free(out);
	out = NULL;
	eds_options strict = { .node_id = 5, .strict = true };
	TEST_ASSERT_EQUAL_INT(-EINVAL, kept(eds_convert_file_opts(path, &strict, &res), &res));
	TEST_ASSERT_NOT_NULL_MESSAGE(
		strstr(err, "sample.eds:121: [1003]: SubNumber=9 but 6 sub-object sections"), err);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_parameter_value_preferred_over_default);
	RUN_TEST(test_nodeid_expressions);
	RUN_TEST(test_bad_expressions);
	RUN_TEST(test_numbers_by_type);
	RUN_TEST(test_wrong_values_for_types);
	RUN_TEST(test_strings_and_domains);
	RUN_TEST(test_ini_syntax_errors);
	RUN_TEST(test_sub_objects);
	RUN_TEST(test_compact_sub_objects);
	RUN_TEST(test_object_links_and_lists);
	RUN_TEST(test_limits);
	RUN_TEST(test_commands_and_read_only_not_written);
	RUN_TEST(test_pdo_remapping_order);
	RUN_TEST(test_lenient_visible_string);
	RUN_TEST(test_lenient_sub_numbers);
	RUN_TEST(test_lenient_values);
	RUN_TEST(test_lenient_types_and_objects);
	RUN_TEST(test_lenient_syntax);
	RUN_TEST(test_file_loader);
	RUN_TEST(test_foreign_eds_files);
	return UNITY_END();
}
