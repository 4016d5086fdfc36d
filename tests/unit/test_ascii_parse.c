/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_ascii_parse.c - the CiA 309-3 command parser and value
 * texts of cogw-ascii (apps/cogw-ascii/ascii_parse.c, ascii_value.c),
 * without sockets or a daemon: every type keyword byte-exact both ways,
 * the command forms of docs/ascii.md, and each error number the parser
 * gives.
 */
#include "unity.h"

#include <errno.h>
#include <string.h>

#include "apps/cogw-ascii/ascii_parse.h"

void setUp(void) {}

void tearDown(void) {}

static uint8_t buf[1024];

static int parse(const char *line, ascii_cmd *cmd)
{
	memset(buf, 0xEE, sizeof buf);
	return ascii_parse(line, strlen(line), cmd, buf, sizeof buf);
}

/* "w" of value as type: the bytes, and "r" printing them gives text back. */
static void check_type(const char *type, const char *value, const uint8_t *bytes, size_t n,
		       const char *printed)
{
	char line[256], text[256];
	ascii_cmd cmd;

	snprintf(line, sizeof line, "[3] 2 5 w 0x2000 1 %s %s", type, value);
	TEST_ASSERT_EQUAL_INT_MESSAGE(ASCII_OK, parse(line, &cmd), line);
	TEST_ASSERT_EQUAL_INT_MESSAGE(ASCII_V_WRITE, cmd.verb, line);
	TEST_ASSERT_EQUAL_size_t_MESSAGE(n, cmd.data_len, line);
	TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(bytes, buf, n, line);
	long tl = ascii_value_format(cmd.type, buf, cmd.data_len, text, sizeof text);

	TEST_ASSERT_TRUE_MESSAGE(tl >= 0, line);
	TEST_ASSERT_EQUAL_STRING_MESSAGE(printed, text, line);
}

static void test_every_type_keyword_both_ways(void)
{
	check_type("b", "1", (const uint8_t[]){ 1 }, 1, "1");
	check_type("b", "false", (const uint8_t[]){ 0 }, 1, "0");
	check_type("i8", "-128", (const uint8_t[]){ 0x80 }, 1, "-128");
	check_type("i16", "-2", (const uint8_t[]){ 0xFE, 0xFF }, 2, "-2");
	check_type("i32", "0x7FFFFFFF", (const uint8_t[]){ 0xFF, 0xFF, 0xFF, 0x7F }, 4,
		   "2147483647");
	check_type("i64", "-9223372036854775808", (const uint8_t[]){ 0, 0, 0, 0, 0, 0, 0, 0x80 }, 8,
		   "-9223372036854775808");
	check_type("u8", "255", (const uint8_t[]){ 0xFF }, 1, "255");
	check_type("u16", "0x1234", (const uint8_t[]){ 0x34, 0x12 }, 2, "4660");
	check_type("u32", "592", (const uint8_t[]){ 0x50, 0x02, 0, 0 }, 4, "592");
	check_type("u64", "18446744073709551615",
		   (const uint8_t[]){ 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF }, 8,
		   "18446744073709551615");
	check_type("x8", "10", (const uint8_t[]){ 10 }, 1, "0x0A");
	check_type("x16", "0xBEEF", (const uint8_t[]){ 0xEF, 0xBE }, 2, "0xBEEF");
	check_type("x32", "0x40194", (const uint8_t[]){ 0x94, 0x01, 0x04, 0x00 }, 4, "0x00040194");
	check_type("x64", "1", (const uint8_t[]){ 1, 0, 0, 0, 0, 0, 0, 0 }, 8,
		   "0x0000000000000001");
	check_type("r32", "1.5", (const uint8_t[]){ 0, 0, 0xC0, 0x3F }, 4, "1.5");
	check_type("r32", "0.1", (const uint8_t[]){ 0xCD, 0xCC, 0xCC, 0x3D }, 4, "0.1");
	check_type("r64", "-2.25", (const uint8_t[]){ 0, 0, 0, 0, 0, 0, 0x02, 0xC0 }, 8, "-2.25");
	/* 14000 days after 1984-01-01, 01:00:00.000 = 3600000 ms */
	check_type("t", "14000 3600000", (const uint8_t[]){ 0x80, 0xEE, 0x36, 0x00, 0xB0, 0x36 }, 6,
		   "14000 3600000");
	check_type("td", "1 0", (const uint8_t[]){ 0, 0, 0, 0, 1, 0 }, 6, "1 0");
	check_type("vs", "\"STI SIM \"\"2\"\"\"", (const uint8_t *)"STI SIM \"2\"", 11,
		   "\"STI SIM \"\"2\"\"\"");
	check_type("vs", "word", (const uint8_t *)"word", 4, "\"word\"");
	check_type("os", "AQID", (const uint8_t[]){ 1, 2, 3 }, 3, "AQID");
	check_type("us", "QQBCAA==", (const uint8_t[]){ 'A', 0, 'B', 0 }, 4, "QQBCAA==");
	check_type("d", "/w==", (const uint8_t[]){ 0xFF }, 1, "/w==");
	check_type("hex", "01 02 0a", (const uint8_t[]){ 1, 2, 10 }, 3, "01 02 0A");
	/* every keyword of the table was exercised above */
	for (const ascii_type *t = ascii_types; t->keyword; t++)
		TEST_ASSERT_NOT_NULL(ascii_type_find(t->keyword, strlen(t->keyword)));
}

static void test_values_out_of_range_or_malformed(void)
{
	static const char *const bad[] = {
		"w 0x2000 1 u8 256",
		"w 0x2000 1 i8 128",
		"w 0x2000 1 i8 -129",
		"w 0x2000 1 u16 -1",
		"w 0x2000 1 u32 12x",
		"w 0x2000 1 u64 18446744073709551616",
		"w 0x2000 1 b 2",
		"w 0x2000 1 r32 1e39",
		"w 0x2000 1 r64 abc",
		"w 0x2000 1 t 1",
		"w 0x2000 1 t 1 86400000",
		"w 0x2000 1 os AQI",
		"w 0x2000 1 d AQ=D",
		"w 0x2000 1 hex 0",
		"w 0x2000 1 vs \"open",
		"w 0x2000 1 u8 1 2",
		"w 0x2000 1 u8",
		"w 0x2000 1 q8 1",
		"r 0x10000 0",
		"r 0x1000 256",
		"r 0x1000",
		"r 0x1000 0 u8 extra",
		"[x] r 0x1000 0",
		"[1",
		"[1]r 0x1000 0",
		"set sdo_timeout 0",
		"set sdo_block 2",
		"reset",
		"reset nothing",
		"lss_switch_glob 2",
		"lss_switch_sel 1 2 3",
		"help me",
		"events maybe",
		"1 2 3 r 0x1000 0",
		"[4]",
	};

	for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
		ascii_cmd cmd;
		char line[128];

		snprintf(line, sizeof line, "%s%s",
			 bad[i][0] == '[' || bad[i][0] == '1' ? "" : "5 ", bad[i]);
		TEST_ASSERT_EQUAL_INT_MESSAGE(ASCII_E_SYNTAX, parse(line, &cmd), line);
	}
}

static void test_command_forms(void)
{
	ascii_cmd cmd;

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[12] 3 7 read 0x1018 1 u32", &cmd));
	TEST_ASSERT_TRUE(cmd.has_seq);
	TEST_ASSERT_EQUAL_UINT32(12, cmd.seq);
	TEST_ASSERT_EQUAL_INT(3, cmd.net);
	TEST_ASSERT_EQUAL_INT(7, cmd.node);
	TEST_ASSERT_EQUAL_INT(ASCII_V_READ, cmd.verb);
	TEST_ASSERT_EQUAL_HEX16(0x1018, cmd.index);
	TEST_ASSERT_EQUAL_UINT8(1, cmd.sub);
	TEST_ASSERT_EQUAL_STRING("u32", cmd.type->keyword);

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("r 0x1000 0", &cmd));
	TEST_ASSERT_FALSE(cmd.has_seq);
	TEST_ASSERT_EQUAL_INT(-1, cmd.net);
	TEST_ASSERT_EQUAL_INT(-1, cmd.node);
	TEST_ASSERT_NULL(cmd.type);

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[1] all start", &cmd));
	TEST_ASSERT_EQUAL_INT(0, cmd.node);
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_START, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("2 0 stop", &cmd));
	TEST_ASSERT_EQUAL_INT(2, cmd.net);
	TEST_ASSERT_EQUAL_INT(0, cmd.node);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 preoperational", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_PREOP, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 preop", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_PREOP, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 reset node", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_RESET_NODE, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 reset comm", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_RESET_COMM, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 reset communication", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_RESET_COMM, cmd.verb);

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[2] 3 set network 4", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_SET_NETWORK, cmd.verb);
	TEST_ASSERT_EQUAL_INT(3, cmd.net);
	TEST_ASSERT_EQUAL_UINT32(4, cmd.args[0]);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("set sdo_timeout 250", &cmd));
	TEST_ASSERT_EQUAL_UINT32(250, cmd.args[0]);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("set sdo_block 1", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_SET_SDO_BLOCK, cmd.verb);

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[9] 1 lss_switch_sel 0x10 2 3 4", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_LSS_SWITCH_SEL, cmd.verb);
	TEST_ASSERT_EQUAL_INT(1, cmd.net);
	TEST_ASSERT_EQUAL_UINT32(4, cmd.n_args);
	TEST_ASSERT_EQUAL_UINT32(0x10, cmd.args[0]);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("lss_inquire_addr", &cmd));
	TEST_ASSERT_EQUAL_UINT32(0, cmd.n_args);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("_lss_fastscan 500", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_LSS_FASTSCAN, cmd.verb);

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[1] info version", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_INFO_VERSION, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("help lss", &cmd));
	TEST_ASSERT_EQUAL_UINT8(2, cmd.help_topic);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("events on emcy hb", &cmd));
	TEST_ASSERT_TRUE(cmd.events_on);
	TEST_ASSERT_EQUAL_HEX32(ASCII_EV_EMCY | ASCII_EV_HB, cmd.events);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("events off", &cmd));
	TEST_ASSERT_EQUAL_HEX32(ASCII_EV_ALL, cmd.events);

	/* comments and blank lines say nothing; a comment may follow a command */
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("# just a comment", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NONE, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("   ", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NONE, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[3] 5 w 0x2000 0 u8 7 # set it", &cmd));
	TEST_ASSERT_EQUAL_size_t(1, cmd.data_len);
	TEST_ASSERT_EQUAL_UINT8(7, buf[0]);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[3] 5 w 0x2000 0 vs \"a # b\"", &cmd));
	TEST_ASSERT_EQUAL_size_t(5, cmd.data_len);
	TEST_ASSERT_EQUAL_MEMORY("a # b", buf, 5);
}

static void test_error_numbers(void)
{
	ascii_cmd cmd;
	static uint8_t small[4];

	TEST_ASSERT_EQUAL_INT(ASCII_E_UNSUPPORTED, parse("5 jump", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_UNSUPPORTED, parse("lss_allnodes", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_UNSUPPORTED, parse("info weather", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_UNSUPPORTED, parse("set colour 1", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_NET, parse("[5] 128 1 r 0x1000 0", &cmd));
	TEST_ASSERT_TRUE(cmd.has_seq); /* the error line carries it */
	TEST_ASSERT_EQUAL_UINT32(5, cmd.seq);
	TEST_ASSERT_EQUAL_INT(ASCII_E_NET, parse("0 1 r 0x1000 0", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_NET, parse("set network 200", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_NODE, parse("128 r 0x1000 0", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_NODE, parse("0 r 0x1000 0", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_NODE, parse("set node 0", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_E_MEMORY, ascii_parse("5 w 0x2000 0 os AQIDBAUG", 24, &cmd,
							  small, sizeof small));
	TEST_ASSERT_EQUAL_INT(ASCII_E_SYNTAX, ascii_parse("5 r\0 0x1000 0", 13, &cmd, buf, 8));
}

static void test_base64_rfc4648_vectors(void)
{
	static const char *const enc[] = { "",         "Zg==",     "Zm8=",    "Zm9v",
					   "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy" };
	char out[16];
	uint8_t back[8];
	size_t n;

	for (size_t i = 0; i < 7; i++) {
		ascii_base64_encode((const uint8_t *)"foobar", i, out);
		TEST_ASSERT_EQUAL_STRING(enc[i], out);
		TEST_ASSERT_EQUAL_INT(0, ascii_base64_decode(enc[i], strlen(enc[i]), back, 8, &n));
		TEST_ASSERT_EQUAL_size_t(i, n);
		if (i)
			TEST_ASSERT_EQUAL_MEMORY("foobar", back, i);
	}
	TEST_ASSERT_EQUAL_INT(-EINVAL, ascii_base64_decode("Zg=a", 4, back, 8, &n));
	TEST_ASSERT_EQUAL_INT(-EINVAL, ascii_base64_decode("Z===", 4, back, 8, &n));
	TEST_ASSERT_EQUAL_INT(-E2BIG, ascii_base64_decode("Zm9vYmFy", 8, back, 5, &n));
}

static void test_value_of_wrong_size_is_refused(void)
{
	char out[64];
	const ascii_type *u32 = ascii_type_find("u32", 3);

	TEST_ASSERT_EQUAL_INT(-EBADMSG, ascii_value_format(u32, (const uint8_t *)"ab", 2, out, 64));
	TEST_ASSERT_EQUAL_INT(-E2BIG, ascii_value_format(u32, (const uint8_t *)"abcd", 4, out, 8));
}

/* Command words, sub-commands and type keywords in any case, as the
 * 309-3 tools take them. */
static void test_any_case(void)
{
	ascii_cmd cmd;

	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("[1] 5 R 0X1018 0 U8", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_READ, cmd.verb);
	TEST_ASSERT_EQUAL_HEX16(0x1018, cmd.index);
	TEST_ASSERT_EQUAL_STRING("u8", cmd.type->keyword);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 READ 0x1018 1 X32", &cmd));
	TEST_ASSERT_EQUAL_STRING("x32", cmd.type->keyword);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 Write 0x2000 0 VS \"Ab\"", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_WRITE, cmd.verb);
	TEST_ASSERT_EQUAL_MEMORY("Ab", buf, 2);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 W 0x2000 0 B TRUE", &cmd));
	TEST_ASSERT_EQUAL_UINT8(1, buf[0]);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("2 ALL START", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_START, cmd.verb);
	TEST_ASSERT_EQUAL_INT(0, cmd.node);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("5 Reset Comm", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_NMT_RESET_COMM, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("SET NETWORK 2", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_SET_NETWORK, cmd.verb);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("1 LSS_GET_NODE", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_V_LSS_GET_NODE, cmd.verb);
	TEST_ASSERT_EQUAL_INT(1, cmd.net);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("Events ON EMCY", &cmd));
	TEST_ASSERT_EQUAL_HEX32(ASCII_EV_EMCY, cmd.events);
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("INFO VERSION", &cmd));
	TEST_ASSERT_EQUAL_INT(ASCII_OK, parse("Help DataType", &cmd));
	TEST_ASSERT_EQUAL_UINT8(1, cmd.help_topic);
	TEST_ASSERT_NOT_NULL(ascii_type_find("R64", 3));
}

/* A line with a NUL byte is a syntax error whose answer still carries the
 * line's sequence number. */
static void test_sequence_kept_on_a_nul_byte(void)
{
	static const char line[] = "[186] 5 r 0x1018\0 0 u8";
	ascii_cmd cmd;

	TEST_ASSERT_EQUAL_INT(ASCII_E_SYNTAX, ascii_parse(line, sizeof line - 1, &cmd, buf, 64));
	TEST_ASSERT_TRUE(cmd.has_seq);
	TEST_ASSERT_EQUAL_UINT32(186, cmd.seq);
}

/* A vs value is printed on one line without NUL, CR or LF, whatever the
 * device sent (a C string with its terminator, say). */
static void test_vs_printed_without_control_bytes(void)
{
	static const uint8_t value[] = { 'a', '"', '\r', 'b', '\n', 'c', 0, 0 };
	const ascii_type *vs = ascii_type_find("vs", 2);
	char out[64];

	TEST_ASSERT_EQUAL_INT(7, ascii_value_format(vs, value, sizeof value, out, sizeof out));
	TEST_ASSERT_EQUAL_STRING("\"a\"\"bc\"", out);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_every_type_keyword_both_ways);
	RUN_TEST(test_values_out_of_range_or_malformed);
	RUN_TEST(test_command_forms);
	RUN_TEST(test_error_numbers);
	RUN_TEST(test_base64_rfc4648_vectors);
	RUN_TEST(test_value_of_wrong_size_is_refused);
	RUN_TEST(test_any_case);
	RUN_TEST(test_sequence_kept_on_a_nul_byte);
	RUN_TEST(test_vs_printed_without_control_bytes);
	return UNITY_END();
}
