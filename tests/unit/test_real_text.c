/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_real_text.c - every printer of REAL32 / REAL64 values
 * gives a text that reads back to the same bits: libcogw's value texts
 * (cogw_value_format: cogwctl's text output and its monitor), the 309-3
 * value texts (ascii_value_format: cogw-ascii, and cogw-mqtt's answers and
 * watches, which put that text into their JSON as it is), cogwctl's --json
 * values (ctl_value_json, ctl_json_add_real: watch, sdo, monitor). Over
 * many random bit patterns, subnormals and the edges of both types.
 */
#include "unity.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "apps/cogw-ascii/ascii_value.h"
#include "apps/common/json_util.h"
#include "apps/cogwctl/ctl.h"

void setUp(void) {}

void tearDown(void) {}

#define RANDOM_VALUES 20000

static uint64_t rng = 0x9E3779B97F4A7C15u;

static uint64_t next_random(void)
{
	/* xorshift64*: the same values on every run */
	rng ^= rng >> 12;
	rng ^= rng << 25;
	rng ^= rng >> 27;
	return rng * 0x2545F4914F6CDD1Du;
}

/* The i-th bit pattern of a REAL64 under test: fixed edges first, then
 * random patterns, every fourth one subnormal (exponent 0). */
static uint64_t double_bits(unsigned i)
{
	static const uint64_t edges[] = {
		0x0000000000000001u, /* the smallest subnormal */
		0x000FFFFFFFFFFFFFu, /* the largest subnormal */
		0x0010000000000000u, /* the smallest normal */
		0x7FEFFFFFFFFFFFFFu, /* the largest finite */
		0x8000000000000000u, /* -0 */
		0x3FB999999999999Au, /* 0.1 */
		0x1F1B504A1531D81Cu, /* 7.771086205726561e-159: 17 digits */
	};
	if (i < sizeof edges / sizeof edges[0])
		return edges[i];
	uint64_t b = next_random();
	if (i % 4 == 0)
		b &= 0x800FFFFFFFFFFFFFu;
	if ((b & 0x7FF0000000000000u) == 0x7FF0000000000000u)
		b ^= 0x0010000000000000u; /* no NaN, no infinity */
	return b;
}

static uint32_t float_bits(unsigned i)
{
	static const uint32_t edges[] = { 0x00000001u, 0x007FFFFFu, 0x00800000u,
					  0x7F7FFFFFu, 0x80000000u, 0x3DCCCCCDu };
	if (i < sizeof edges / sizeof edges[0])
		return edges[i];
	uint32_t b = (uint32_t)(next_random() >> 32);
	if (i % 4 == 0)
		b &= 0x807FFFFFu;
	if ((b & 0x7F800000u) == 0x7F800000u)
		b ^= 0x00800000u;
	return b;
}

static void put_le(uint8_t *d, size_t n, uint64_t v)
{
	for (size_t i = 0; i < n; i++)
		d[i] = (uint8_t)(v >> (8 * i));
}

/* The text must read back to exactly the bits (REAL32: through strtof). */
static void expect_exact(const char *who, const char *text, uint64_t bits, bool single)
{
	char msg[160];
	snprintf(msg, sizeof msg, "%s printed %s for the bits %016llx", who, text,
		 (unsigned long long)bits);
	if (single) {
		float f = strtof(text, NULL);
		uint32_t back;
		memcpy(&back, &f, 4);
		TEST_ASSERT_EQUAL_HEX32_MESSAGE((uint32_t)bits, back, msg);
	} else {
		double d = strtod(text, NULL);
		uint64_t back;
		memcpy(&back, &d, 8);
		TEST_ASSERT_EQUAL_HEX64_MESSAGE(bits, back, msg);
	}
}

/* One value through every printer. */
static void check_printers(uint64_t bits, bool single)
{
	uint8_t data[8];
	size_t size = single ? 4 : 8;
	char text[64];

	put_le(data, size, bits);
	TEST_ASSERT_TRUE(cogw_value_format(single ? MBX_T_REAL32 : MBX_T_REAL64, data, size, text,
					   sizeof text) > 0);
	expect_exact("cogw_value_format", text, bits, single);

	const ascii_type *t = ascii_type_find(single ? "r32" : "r64", 3);
	TEST_ASSERT_TRUE(ascii_value_format(t, data, size, text, sizeof text) > 0);
	expect_exact("ascii_value_format", text, bits, single);

	cJSON *o = cJSON_CreateObject();
	ctl_value_json(o, ctl_type_find(single ? "r32" : "r64"), data, size);
	char *json = cJSON_PrintUnformatted(o);
	cJSON *back = cJSON_Parse(json);
	const char *at = strstr(json, "\"value\":");
	TEST_ASSERT_NOT_NULL_MESSAGE(at, json);
	TEST_ASSERT_TRUE_MESSAGE(cJSON_IsNumber(cJSON_GetObjectItem(back, "value")), json);
	expect_exact("ctl_value_json", at + 8, bits, single);
	cJSON_Delete(back);
	free(json);
	cJSON_Delete(o);

	/* cogwctl monitor --json: "r32" of a 4-byte PDO value */
	if (single) {
		o = cJSON_CreateObject();
		ctl_json_add_real(o, "r32", CO_T_REAL32, data);
		json = cJSON_PrintUnformatted(o);
		expect_exact("ctl_json_add_real", strstr(json, ":") + 1, bits, true);
		free(json);
		cJSON_Delete(o);
	}
}

static void test_real64_texts_read_back_exactly(void)
{
	for (unsigned i = 0; i < RANDOM_VALUES; i++)
		check_printers(double_bits(i), false);
}

static void test_real32_texts_read_back_exactly(void)
{
	for (unsigned i = 0; i < RANDOM_VALUES; i++)
		check_printers(float_bits(i), true);
}

/* A REAL in JSON always reads as a floating-point number: "-0.0", never
 * the integer-looking "-0" that most readers take as 0. */
static void test_json_real_is_never_an_integer(void)
{
	static const struct {
		uint64_t bits;
		const char *json;
	} cases[] = { { 0x8000000000000000u, "{\"value\":-0.0}" },
		      { 0x0000000000000000u, "{\"value\":0.0}" },
		      { 0x4059000000000000u, "{\"value\":100.0}" },
		      { 0x3FF8000000000000u, "{\"value\":1.5}" } };

	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		uint8_t data[8];
		cJSON *o = cJSON_CreateObject();

		put_le(data, 8, cases[i].bits);
		ctl_json_add_real(o, "value", CO_T_REAL64, data);
		char *json = cJSON_PrintUnformatted(o);
		TEST_ASSERT_EQUAL_STRING(cases[i].json, json);
		free(json);
		cJSON_Delete(o);
	}
	cJSON *v = json_util_real_number("-0");
	char *json = cJSON_PrintUnformatted(v);
	TEST_ASSERT_EQUAL_STRING("-0.0", json);
	free(json);
	cJSON_Delete(v);
}

/* JSON has no number for NaN or an infinity: cogwctl gives null. */
static void test_json_of_a_non_finite_real_is_null(void)
{
	uint8_t data[8];
	cJSON *o = cJSON_CreateObject();

	put_le(data, 8, 0x7FF0000000000000u);
	ctl_value_json(o, ctl_type_find("r64"), data, 8);
	TEST_ASSERT_TRUE(cJSON_IsNull(cJSON_GetObjectItem(o, "value")));
	cJSON_Delete(o);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_real64_texts_read_back_exactly);
	RUN_TEST(test_real32_texts_read_back_exactly);
	RUN_TEST(test_json_of_a_non_finite_real_is_null);
	RUN_TEST(test_json_real_is_never_an_integer);
	return UNITY_END();
}
