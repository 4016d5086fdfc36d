/* SPDX-License-Identifier: MIT */
/*
 * libcogw's typed value texts (cogw_value_format/parse, cogw_type_*) that
 * every client shares, the DEV_LAYOUT answer walk and the mailbox checks of
 * the device object commands: every CiA 301 basic type both ways, range
 * and syntax refusals, a layout answer whose counts lie, a type number
 * that is no basic type.
 */
#include <string.h>

#include "unity.h"

#include "mailbox/cogw.h"
#include "mailbox/proto.h"

void setUp(void) {}

void tearDown(void) {}

static void expect_text(uint16_t type, const char *hex, const char *want)
{
	uint8_t data[16];
	size_t n = 0;
	for (const char *p = hex; p[0] && p[1]; p += 2 + (p[2] == ' '))
		sscanf(p, "%2hhx", &data[n++]);
	char out[64];
	int len = cogw_value_format(type, data, n, out, sizeof out);
	TEST_ASSERT_EQUAL_STRING(want, out);
	TEST_ASSERT_EQUAL_INT((int)strlen(want), len);
	/* and back: the text parses to the same bytes */
	uint8_t back[16];
	size_t blen = 0;
	TEST_ASSERT_EQUAL_INT(0, cogw_value_parse(type, out, back, sizeof back, &blen));
	TEST_ASSERT_EQUAL_size_t(n, blen);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(data, back, n);
}

void test_every_basic_type_both_ways(void)
{
	expect_text(MBX_T_BOOLEAN, "01", "true");
	expect_text(MBX_T_BOOLEAN, "00", "false");
	expect_text(MBX_T_INTEGER8, "9c", "-100");
	expect_text(MBX_T_INTEGER16, "c7 cf", "-12345");
	expect_text(MBX_T_INTEGER24, "c0 bd f0", "-1000000");
	expect_text(MBX_T_INTEGER32, "eb 32 a4 f8", "-123456789");
	expect_text(MBX_T_INTEGER40, "fe ff ff ff ff", "-2");
	expect_text(MBX_T_INTEGER48, "00 00 00 00 00 80", "-140737488355328");
	expect_text(MBX_T_INTEGER56, "ff ff ff ff ff ff 7f", "36028797018963967");
	expect_text(MBX_T_INTEGER64, "01 00 00 00 00 00 00 80", "-9223372036854775807");
	expect_text(MBX_T_UNSIGNED8, "c8", "200");
	expect_text(MBX_T_UNSIGNED16, "ff ff", "65535");
	expect_text(MBX_T_UNSIGNED24, "ef cd ab", "11259375");
	expect_text(MBX_T_UNSIGNED32, "ef be ad de", "3735928559");
	expect_text(MBX_T_UNSIGNED40, "05 04 03 02 01", "4328719365");
	expect_text(MBX_T_UNSIGNED48, "bc 9a 78 56 34 12", "20015998343868");
	expect_text(MBX_T_UNSIGNED56, "99 aa bb cc dd ee ff", "72038755451251353");
	expect_text(MBX_T_UNSIGNED64, "10 32 54 76 98 ba dc fe", "18364758544493064720");
	expect_text(MBX_T_REAL32, "00 00 c0 3f", "1.5");
	expect_text(MBX_T_REAL32, "cd cc cc 3d", "0.1");
	expect_text(MBX_T_REAL64, "00 00 00 00 00 00 02 c0", "-2.25");
	expect_text(MBX_T_REAL64, "9a 99 99 99 99 99 b9 3f", "0.1");
	expect_text(MBX_T_VISIBLE_STRING, "6f 6b", "ok");
	expect_text(MBX_T_OCTET_STRING, "5a 00 ff", "5a 00 ff");
	expect_text(MBX_T_DOMAIN, "de ad", "de ad");
	/* TIME_OF_DAY: ms after midnight (28 bits), days since 1984 */
	expect_text(MBX_T_TIME_OF_DAY, "e8 03 00 00 10 27", "10000 1000");
}

void test_parse_refuses_out_of_range_and_bad_syntax(void)
{
	uint8_t out[8];
	size_t n;
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM,
			      cogw_value_parse(MBX_T_UNSIGNED16, "70000", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_value_parse(MBX_T_INTEGER8, "-129", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_value_parse(MBX_T_UNSIGNED8, "-1", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM,
			      cogw_value_parse(MBX_T_INTEGER24, "8388608", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_value_parse(MBX_T_REAL32, "1e39", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL,
			      cogw_value_parse(MBX_T_UNSIGNED16, "12abc", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_value_parse(MBX_T_UNSIGNED16, " 1", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_value_parse(MBX_T_BOOLEAN, "yes", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_value_parse(MBX_T_OCTET_STRING, "0g", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_TRUNCATED,
			      cogw_value_parse(MBX_T_VISIBLE_STRING, "123456789", out, 8, &n));
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_value_parse(0x0E, "1", out, 8, &n));
	/* 0x hex is accepted for integers */
	TEST_ASSERT_EQUAL_INT(0, cogw_value_parse(MBX_T_UNSIGNED16, "0x1234", out, 8, &n));
	TEST_ASSERT_EQUAL_HEX8(0x34, out[0]);
	TEST_ASSERT_EQUAL_HEX8(0x12, out[1]);
	/* a value whose length is not its type's cannot be shown as it */
	char text[32];
	TEST_ASSERT_EQUAL_INT(COGW_E_INVAL, cogw_value_format(MBX_T_UNSIGNED16, out, 3, text, 32));
	TEST_ASSERT_EQUAL_INT(COGW_E_TRUNCATED,
			      cogw_value_format(MBX_T_UNSIGNED64, out, 8, text, 4));
}

void test_type_names(void)
{
	TEST_ASSERT_EQUAL_HEX16(MBX_T_INTEGER24, cogw_type_find("i24")->type);
	TEST_ASSERT_EQUAL_HEX16(MBX_T_INTEGER24, cogw_type_find("integer24")->type);
	TEST_ASSERT_EQUAL_STRING("UNSIGNED56", cogw_type_of(MBX_T_UNSIGNED56)->cia_name);
	TEST_ASSERT_EQUAL(7, cogw_type_of(MBX_T_UNSIGNED56)->size);
	TEST_ASSERT_NULL(cogw_type_find("u33"));
	TEST_ASSERT_NULL(cogw_type_of(0x17));
}

void test_layout_answer_walk(void)
{
	uint8_t buf[256];
	size_t off = 0;
	mbx_dev_layout_node n = { .node = 5, .n_tpdo = 1, .n_rpdo = 1 };
	mbx_dev_layout_pdo t = { .nr = 1, .dir = 1, .n = 2 }, r = { .nr = 1, .n = 1 };
	mbx_dev_layout_entry e = { .index = 0x6000, .sub = 1, .bits = 8 };
	memcpy(buf + off, &n, sizeof n), off += sizeof n;
	memcpy(buf + off, &t, sizeof t), off += sizeof t;
	memcpy(buf + off, &e, sizeof e), off += sizeof e;
	memcpy(buf + off, &e, sizeof e), off += sizeof e;
	memcpy(buf + off, &r, sizeof r), off += sizeof r;
	memcpy(buf + off, &e, sizeof e), off += sizeof e;
	TEST_ASSERT_EQUAL_INT(1, cogw_dev_layout_check(buf, off));
	TEST_ASSERT_EQUAL_INT(0, cogw_dev_layout_check(buf, 0));
	/* one byte short, or a record count that promises more */
	TEST_ASSERT_EQUAL_INT(COGW_E_PROTOCOL, cogw_dev_layout_check(buf, off - 1));
	n.n_rpdo = 2;
	memcpy(buf, &n, sizeof n);
	TEST_ASSERT_EQUAL_INT(COGW_E_PROTOCOL, cogw_dev_layout_check(buf, off));
}

void test_value_event_parse(void)
{
	uint8_t buf[sizeof(mbx_dev_value) + 8];
	mbx_dev_value v = { .node = 5, .type = MBX_T_INTEGER16, .len = 2 }, got;
	const uint8_t *data;
	memcpy(buf, &v, sizeof v);
	buf[sizeof v] = 0xC7;
	buf[sizeof v + 1] = 0xCF;
	TEST_ASSERT_EQUAL_INT(0, cogw_dev_value_parse(buf, sizeof v + 2, &got, &data));
	TEST_ASSERT_EQUAL_HEX8(0xC7, data[0]);
	TEST_ASSERT_EQUAL_INT(COGW_E_PROTOCOL,
			      cogw_dev_value_parse(buf, sizeof v + 3, &got, &data));
	TEST_ASSERT_EQUAL_INT(COGW_E_PROTOCOL, cogw_dev_value_parse(buf, 10, &got, &data));
}

/* The mailbox's check of a DEV_WATCH command with this payload. */
static int validate_watch(const mbx_dev_watch_req *w, mbx_bad *bad)
{
	static uint8_t msg[256];
	mbx_hdr h = { .magic = MBX_MAGIC,
		      .version = MBX_VERSION,
		      .kind = MBX_KIND_COMMAND,
		      .code = MBX_CMD_DEV_WATCH,
		      .client = 0x00010002,
		      .corr = 7,
		      .token = 9 },
		d;
	int n = mbx_msg_build(msg, sizeof msg, &h, w, sizeof *w);
	TEST_ASSERT_TRUE(n > 0);
	TEST_ASSERT_EQUAL_INT(0, mbx_hdr_decode(msg, (size_t)n, &d, bad));
	return mbx_cmd_validate(&d, msg + MBX_HDR_SIZE, bad);
}

void test_device_object_commands_are_checked(void)
{
	mbx_dev_watch_req w = { .obj = { .node = 5, .index = 0x6000, .sub = 1 } };
	mbx_bad bad = MBX_BAD_NONE;
	TEST_ASSERT_EQUAL_INT(0, validate_watch(&w, &bad));
	w.obj.type = 0x0E; /* no basic type */
	TEST_ASSERT_EQUAL_INT(MBX_E_PARAM, validate_watch(&w, &bad));
	TEST_ASSERT_EQUAL_STRING(mbx_bad_to_string(MBX_BAD_PARAM), mbx_bad_to_string(bad));
	w.obj.type = MBX_T_UNSIGNED64;
	TEST_ASSERT_EQUAL_INT(0, validate_watch(&w, &bad));
	w.obj.node = 0;
	TEST_ASSERT_EQUAL_INT(MBX_E_PARAM, validate_watch(&w, &bad));
	w.obj.node = 5;
	w.obj.flags = 2; /* reserved */
	TEST_ASSERT_NOT_EQUAL(0, validate_watch(&w, &bad));
	TEST_ASSERT_EQUAL_STRING(mbx_bad_to_string(MBX_BAD_RESERVED), mbx_bad_to_string(bad));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_every_basic_type_both_ways);
	RUN_TEST(test_parse_refuses_out_of_range_and_bad_syntax);
	RUN_TEST(test_type_names);
	RUN_TEST(test_layout_answer_walk);
	RUN_TEST(test_value_event_parse);
	RUN_TEST(test_device_object_commands_are_checked);
	return UNITY_END();
}
