/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_fuzz_mqtt_request_corpus.c - replays the fuzz corpus
 * tests/fuzz/corpus/mqtt_request/ through the very fuzz target body
 * (tests/fuzz/fuzz_mqtt_request.c, included below), so that the gcc
 * sanitizer build checks the same properties where clang/libFuzzer is not
 * installed. Files named valid_* must be accepted, bad_* refused; every
 * prefix of every file is replayed too (a payload cut anywhere).
 *
 * Run from the repository root (make unit does), or set COGW_SRC_DIR.
 */
#include "unity.h"

#include "tests/fuzz/fuzz_mqtt_request.c"
#include "tests/unit/support/corpus.h"

void setUp(void) {}
void tearDown(void) {}

static bool accepted(const uint8_t *data, size_t size)
{
	static mqtt_request r;
	char err[512];

	return mqtt_request_decode(data, size, FUZZ_MAX_PAYLOAD, &r, err, sizeof err) ==
	       MQTT_REQ_OK;
}

static void test_corpus_replay(void)
{
	TEST_ASSERT_TRUE_MESSAGE(corpus_replay("mqtt_request", fuzz_mqtt_request_one, accepted) >=
					 10,
				 "corpus has fewer than 10 files");
}

/* The reasons a requester reads (docs/mqtt.md "Errors"). */
static void test_refusals_name_the_field(void)
{
	static mqtt_request r;
	char err[512];
	static const struct {
		const char *payload;
		int rc;
		const char *reason;
	} cases[] = {
		{ "{\"op\":\"sdo_read\",\"net\":1,\"node\":128,\"index\":1,\"sub\":0,\"type\":"
		  "\"u8\"}",
		  MQTT_REQ_BAD_FIELD, "node: 128 is out of range" },
		{ "{\"op\":\"sdo_read\",\"net\":0,\"node\":1,\"index\":1,\"sub\":0,\"type\":"
		  "\"u8\"}",
		  MQTT_REQ_BAD_FIELD, "net: 0 is out of range" },
		{ "{\"op\":\"sdo_write\",\"net\":1,\"node\":1,\"index\":1,\"sub\":0,\"type\":"
		  "\"i8\","
		  "\"value\":-129}",
		  MQTT_REQ_BAD_FIELD, "value: out of the range of i8" },
		{ "{\"op\":\"sdo_write\",\"net\":1,\"node\":1,\"index\":1,\"sub\":0,\"type\":"
		  "\"u64\","
		  "\"value\":1e300}",
		  MQTT_REQ_BAD_FIELD, "value: an integer type needs an integer" },
		{ "{\"op\":\"nmt\",\"net\":1,\"node\":0,\"command\":\"reboot\"}",
		  MQTT_REQ_BAD_FIELD, "command: \"reboot\" is not one of" },
		{ "{\"op\":\"sdo_read\",\"reply_to\":\"a/+/b\"}", MQTT_REQ_BAD_FIELD, "reply_to:" },
		{ "{\"id\":\"x\"}", MQTT_REQ_BAD_OP, "op: required key is missing" },
		{ "\"op\"", MQTT_REQ_MALFORMED, "must be an object" },
	};

	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		int rc = mqtt_request_decode(cases[i].payload, strlen(cases[i].payload), 4096, &r,
					     err, sizeof err);

		TEST_ASSERT_EQUAL_INT_MESSAGE(cases[i].rc, rc, cases[i].payload);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, cases[i].reason), err);
	}
}

/* The id and reply_to come back with a refusal for any other field. */
static void test_refusal_keeps_the_return_path(void)
{
	static mqtt_request r;
	char err[512];
	const char *p =
		"{\"id\":42,\"reply_to\":\"plant/replies/7\",\"op\":\"sdo_read\",\"net\":1}";

	TEST_ASSERT_EQUAL_INT(MQTT_REQ_BAD_FIELD,
			      mqtt_request_decode(p, strlen(p), 4096, &r, err, sizeof err));
	TEST_ASSERT_EQUAL_STRING("42", r.id);
	TEST_ASSERT_EQUAL_STRING("plant/replies/7", r.reply_to);
}

static void test_values_encode_as_the_type_says(void)
{
	static mqtt_request r;
	char err[512];
	const char *p = "{\"op\":\"sdo_write\",\"net\":2,\"node\":5,\"index\":\"0x2001\",\"sub\":3,"
			"\"type\":\"u32\",\"value\":\"0x12345678\"}";

	TEST_ASSERT_EQUAL_INT(MQTT_REQ_OK,
			      mqtt_request_decode(p, strlen(p), 4096, &r, err, sizeof err));
	TEST_ASSERT_EQUAL_UINT16(0x2001, r.index);
	TEST_ASSERT_EQUAL_UINT(4, r.value_len);
	TEST_ASSERT_EQUAL_HEX8(0x78, r.value[0]);
	TEST_ASSERT_EQUAL_HEX8(0x12, r.value[3]);
	p = "{\"op\":\"sdo_write\",\"net\":2,\"node\":5,\"index\":8193,\"sub\":0,\"type\":\"r32\","
	    "\"value\":1.5}";
	TEST_ASSERT_EQUAL_INT(MQTT_REQ_OK,
			      mqtt_request_decode(p, strlen(p), 4096, &r, err, sizeof err));
	float f;
	memcpy(&f, r.value, 4);
	TEST_ASSERT_EQUAL_FLOAT(1.5f, f);
	p = "{\"op\":\"sdo_write\",\"net\":2,\"node\":5,\"index\":8193,\"sub\":0,\"type\":\"vs\","
	    "\"value\":\"abc\"}";
	TEST_ASSERT_EQUAL_INT(MQTT_REQ_OK,
			      mqtt_request_decode(p, strlen(p), 4096, &r, err, sizeof err));
	TEST_ASSERT_EQUAL_UINT(3, r.value_len);
	TEST_ASSERT_EQUAL_MEMORY("abc", r.value, 3);
}

static void test_oversized_payload_is_refused_unread(void)
{
	static mqtt_request r;
	static char big[5000];
	char err[512];

	memset(big, ' ', sizeof big);
	TEST_ASSERT_EQUAL_INT(MQTT_REQ_TOO_BIG,
			      mqtt_request_decode(big, sizeof big, 4096, &r, err, sizeof err));
	TEST_ASSERT_NOT_NULL(strstr(err, "limit is 4096"));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_corpus_replay);
	RUN_TEST(test_refusals_name_the_field);
	RUN_TEST(test_refusal_keeps_the_return_path);
	RUN_TEST(test_values_encode_as_the_type_says);
	RUN_TEST(test_oversized_payload_is_refused_unread);
	return UNITY_END();
}
