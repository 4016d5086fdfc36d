/* SPDX-License-Identifier: MIT */
/*
 * Object dictionary: types, building, lookup (gaps, abort reasons, many
 * objects added at run time in random order), typed access, checks and
 * limits, hooks, defaults; CRC-16 check value.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#include "core/crc16.h"
#include "core/frame.h"
#include "core/od.h"
#include "core/sdo.h"
#include "tests/unit/support/test_od_fixture.h"

static co_od *od;

void setUp(void)
{
	od = fx_od_new();
}

void tearDown(void)
{
	co_od_destroy(od);
}

static void test_type_table(void)
{
	TEST_ASSERT_EQUAL_STRING("UNSIGNED32", co_type_to_string(CO_T_UNSIGNED32));
	TEST_ASSERT_EQUAL_STRING("TIME_DIFFERENCE", co_type_to_string(CO_T_TIME_DIFFERENCE));
	TEST_ASSERT_EQUAL_STRING("?", co_type_to_string((co_type)0x17));
	TEST_ASSERT_EQUAL(1, co_type_size(CO_T_BOOLEAN));
	TEST_ASSERT_EQUAL(3, co_type_size(CO_T_INTEGER24));
	TEST_ASSERT_EQUAL(5, co_type_size(CO_T_UNSIGNED40));
	TEST_ASSERT_EQUAL(6, co_type_size(CO_T_TIME_OF_DAY));
	TEST_ASSERT_EQUAL(7, co_type_size(CO_T_INTEGER56));
	TEST_ASSERT_EQUAL(8, co_type_size(CO_T_REAL64));
	TEST_ASSERT_EQUAL(0, co_type_size(CO_T_DOMAIN));
	TEST_ASSERT_TRUE(co_type_is_variable(CO_T_UNICODE_STRING));
	TEST_ASSERT_TRUE(co_type_is_signed(CO_T_INTEGER40));
	TEST_ASSERT_FALSE(co_type_is_signed(CO_T_UNSIGNED8));
	TEST_ASSERT_TRUE(co_type_is_real(CO_T_REAL32));
	TEST_ASSERT_FALSE(co_type_is_valid((co_type)0x0E));
	TEST_ASSERT_EQUAL_STRING("RECORD", co_obj_code_to_string(CO_OBJ_RECORD));
	TEST_ASSERT_EQUAL_STRING("sdo", co_od_origin_to_string(CO_OD_ORIGIN_SDO));
	TEST_ASSERT_EQUAL_STRING("object does not exist", sdo_abort_to_string(0x06020000));
	TEST_ASSERT_EQUAL_STRING("unknown abort code", sdo_abort_to_string(0x12345678));
	TEST_ASSERT_EQUAL_STRING("block", sdo_mode_to_string(SDO_MODE_BLOCK));
}

static void test_every_basic_type_can_be_added(void)
{
	static const co_type types[] = {
		CO_T_BOOLEAN,         CO_T_INTEGER8,   CO_T_INTEGER16,  CO_T_INTEGER24,
		CO_T_INTEGER32,       CO_T_INTEGER40,  CO_T_INTEGER48,  CO_T_INTEGER56,
		CO_T_INTEGER64,       CO_T_UNSIGNED8,  CO_T_UNSIGNED16, CO_T_UNSIGNED24,
		CO_T_UNSIGNED32,      CO_T_UNSIGNED40, CO_T_UNSIGNED48, CO_T_UNSIGNED56,
		CO_T_UNSIGNED64,      CO_T_REAL32,     CO_T_REAL64,     CO_T_TIME_OF_DAY,
		CO_T_TIME_DIFFERENCE,
	};
	co_od_entry *e;

	for (unsigned i = 0; i < sizeof(types) / sizeof(types[0]); i++) {
		TEST_ASSERT_EQUAL(
			0, co_od_add_num(od, 0x3000, (uint8_t)(i + 1), types[i], CO_ACC_RW, 1, &e));
		TEST_ASSERT_EQUAL_UINT32(co_type_size(types[i]), e->size);
		TEST_ASSERT_EQUAL_UINT64(1, co_od_entry_raw(e));
	}
	TEST_ASSERT_EQUAL(0, co_od_add_bytes(od, 0x3001, 0, CO_T_VISIBLE_STRING, CO_ACC_RW, 10,
					     "abc", 3, &e));
	TEST_ASSERT_EQUAL_STRING("abc", (const char *)e->data);
	TEST_ASSERT_EQUAL(
		0, co_od_add_bytes(od, 0x3002, 0, CO_T_OCTET_STRING, CO_ACC_RW, 4, NULL, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_bytes(od, 0x3003, 0, CO_T_UNICODE_STRING, CO_ACC_RW, 8,
					     "a\0b\0", 4, NULL));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_bytes(od, 0x3004, 0, CO_T_DOMAIN, CO_ACC_RW, 0, NULL, 0, &e));
	TEST_ASSERT_EQUAL_UINT32(0, e->size);
	/* Bad descriptors. */
	TEST_ASSERT_EQUAL(-EINVAL, co_od_add_num(od, 0x3005, 0, CO_T_DOMAIN, CO_ACC_RW, 0, NULL));
	TEST_ASSERT_EQUAL(-EINVAL, co_od_add_bytes(od, 0x3005, 0, CO_T_UNSIGNED8, CO_ACC_RW, 1,
						   NULL, 0, NULL));
	TEST_ASSERT_EQUAL(
		-EINVAL, co_od_add_bytes(od, 0x3005, 0, CO_T_DOMAIN, CO_ACC_RW, 2, "abc", 3, NULL));
	co_od_desc d = { .index = 0x3005, .type = 0x0E };
	TEST_ASSERT_EQUAL(-EINVAL, co_od_add(od, &d, NULL));
	d.type = CO_T_UNSIGNED16;
	d.def = "x";
	d.def_size = 1;
	TEST_ASSERT_EQUAL(-EINVAL, co_od_add(od, &d, NULL));
	TEST_ASSERT_EQUAL(-EEXIST,
			  co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, 0, NULL));
}

static void test_lookup_and_abort_reasons(void)
{
	uint32_t ab;

	TEST_ASSERT_NOT_NULL(co_od_find(od, 0x1018, 4));
	TEST_ASSERT_NULL(co_od_find_ex(od, 0x1018, 5, &ab));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_SUB, ab);
	TEST_ASSERT_NULL(co_od_find_ex(od, 0x2104, 2, &ab)); /* gap */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_SUB, ab);
	TEST_ASSERT_NOT_NULL(co_od_find_ex(od, 0x2104, 3, &ab));
	TEST_ASSERT_EQUAL_HEX32(0, ab);
	TEST_ASSERT_NULL(co_od_find_ex(od, 0x2001, 0, &ab));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, ab);
	TEST_ASSERT_NULL(co_od_find_ex(od, 0x0000, 0, &ab));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, ab);
	TEST_ASSERT_NULL(co_od_find_ex(od, 0xFFFF, 0xFF, &ab));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, ab);
	TEST_ASSERT_TRUE(co_od_has_index(od, 0x2104));
	TEST_ASSERT_FALSE(co_od_has_index(od, 0x2105));
	/* Iteration is sorted. */
	uint32_t prev = 0;
	for (size_t i = 0; i < co_od_count(od); i++) {
		co_od_entry *e = co_od_at(od, i);
		uint32_t key = ((uint32_t)e->index << 8) | e->sub;
		TEST_ASSERT_TRUE(i == 0 || key > prev);
		prev = key;
	}
	TEST_ASSERT_NULL(co_od_at(od, co_od_count(od)));
}

static void test_runtime_add_many_random_order_pointers_stable(void)
{
	enum {
		N = 4000
	};
	co_od_entry *first;
	unsigned seed = 12345;
	static uint16_t idx[N];

	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(od, 0x4000, 0, CO_T_UNSIGNED32, CO_ACC_RW, 0xAB, &first));
	for (unsigned i = 0; i < N; i++)
		idx[i] = (uint16_t)(0x4001 + i);
	for (unsigned i = N - 1; i > 0; i--) { /* shuffle */
		seed = seed * 1103515245u + 12345u;
		unsigned j = (seed >> 8) % (i + 1);
		uint16_t t = idx[i];
		idx[i] = idx[j];
		idx[j] = t;
	}
	for (unsigned i = 0; i < N; i++)
		TEST_ASSERT_EQUAL(0, co_od_add_num(od, idx[i], (uint8_t)(idx[i] & 0x7F),
						   CO_T_UNSIGNED16, CO_ACC_RW, idx[i], NULL));
	TEST_ASSERT_EQUAL_PTR(first, co_od_find(od, 0x4000, 0));
	TEST_ASSERT_EQUAL_UINT64(0xAB, co_od_entry_raw(first));
	for (unsigned i = 0; i < N; i++) {
		uint16_t x = (uint16_t)(0x4001 + i);
		co_od_entry *e = co_od_find(od, x, (uint8_t)(x & 0x7F));
		TEST_ASSERT_NOT_NULL(e);
		TEST_ASSERT_EQUAL_UINT64(x, co_od_entry_raw(e));
		TEST_ASSERT_NULL(co_od_find(od, x, (uint8_t)((x & 0x7F) + 1)));
	}
}

static void test_typed_get_set(void)
{
	uint8_t u8;
	uint16_t u16;
	uint32_t u32;
	uint64_t u64;
	int8_t i8;
	int16_t i16;
	int32_t i32;
	int64_t i64;
	float r32;
	double r64;

	TEST_ASSERT_EQUAL(0, co_od_get_u32(od, 0x1000, 0, &u32));
	TEST_ASSERT_EQUAL_HEX32(0x00040194, u32);
	TEST_ASSERT_EQUAL(0, co_od_get_u64(od, 0x1000, 0, &u64));       /* widening ok */
	TEST_ASSERT_EQUAL(-EINVAL, co_od_get_u16(od, 0x1000, 0, &u16)); /* narrowing not */
	TEST_ASSERT_EQUAL(-ENOENT, co_od_get_u8(od, 0x2001, 0, &u8));
	TEST_ASSERT_EQUAL(-EINVAL, co_od_get_u32(od, 0x1008, 0, &u32)); /* string */
	TEST_ASSERT_EQUAL(-EINVAL, co_od_get_u32(od, 0x2004, 1, &u32)); /* real */

	TEST_ASSERT_EQUAL(0, co_od_set_i16(od, FX_IDX_SIGNED, 0, -5));
	TEST_ASSERT_EQUAL(0, co_od_get_i16(od, FX_IDX_SIGNED, 0, &i16));
	TEST_ASSERT_EQUAL_INT16(-5, i16);
	TEST_ASSERT_EQUAL(0, co_od_get_i32(od, FX_IDX_SIGNED, 0, &i32)); /* sign-extended */
	TEST_ASSERT_EQUAL_INT32(-5, i32);
	TEST_ASSERT_EQUAL(0, co_od_get_i64(od, FX_IDX_SIGNED, 0, &i64));
	TEST_ASSERT_EQUAL_INT64(-5, i64);
	TEST_ASSERT_EQUAL(0, co_od_get_u16(od, FX_IDX_SIGNED, 0, &u16)); /* raw bits */
	TEST_ASSERT_EQUAL_HEX16(0xFFFB, u16);
	TEST_ASSERT_EQUAL(-ERANGE, co_od_set_i32(od, FX_IDX_SIGNED, 0, 40000));
	TEST_ASSERT_EQUAL(0, co_od_set_i32(od, FX_IDX_SIGNED, 0, -32768));
	TEST_ASSERT_EQUAL(-ERANGE, co_od_set_u32(od, 0x1017, 0, 0x10000));
	TEST_ASSERT_EQUAL(0, co_od_set_u8(od, 0x1017, 0, 200));
	TEST_ASSERT_EQUAL(-ERANGE, co_od_set_u8(od, FX_IDX_BOOL, 0, 2));
	TEST_ASSERT_EQUAL(0, co_od_set_u8(od, FX_IDX_BOOL, 0, 1));
	TEST_ASSERT_EQUAL(-EINVAL, co_od_get_i8(od, 0x1017, 0, &i8));

	TEST_ASSERT_EQUAL(0, co_od_set_u64(od, FX_IDX_U64, 0, 0x0123456789ABCDEFull));
	TEST_ASSERT_EQUAL(0, co_od_get_u64(od, FX_IDX_U64, 0, &u64));
	TEST_ASSERT_EQUAL_HEX64(0x0123456789ABCDEFull, u64);
	TEST_ASSERT_EQUAL_HEX8(0xEF, co_od_find(od, FX_IDX_U64, 0)->data[0]); /* LE */

	TEST_ASSERT_EQUAL(0, co_od_set_r32(od, 0x2004, 1, 1.23f));
	TEST_ASSERT_EQUAL(0, co_od_get_r32(od, 0x2004, 1, &r32));
	TEST_ASSERT_EQUAL_FLOAT(1.23f, r32);
	TEST_ASSERT_EQUAL_MEMORY("\xA4\x70\x9D\x3F", co_od_find(od, 0x2004, 1)->data, 4);
	TEST_ASSERT_EQUAL(-EINVAL, co_od_get_r64(od, 0x2004, 1, &r64));
	co_od_entry *e;
	TEST_ASSERT_EQUAL(0, co_od_add_num(od, 0x3100, 0, CO_T_REAL64, CO_ACC_RW, 0, &e));
	TEST_ASSERT_EQUAL(0, co_od_set_r64(od, 0x3100, 0, -2.5));
	TEST_ASSERT_EQUAL(0, co_od_get_r64(od, 0x3100, 0, &r64));
	TEST_ASSERT_TRUE(r64 == -2.5);

	/* INTEGER24 sign extension */
	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(od, 0x3101, 0, CO_T_INTEGER24, CO_ACC_RW, 0xFFFFFE, NULL));
	TEST_ASSERT_EQUAL(0, co_od_get_i32(od, 0x3101, 0, &i32));
	TEST_ASSERT_EQUAL_INT32(-2, i32);
	TEST_ASSERT_EQUAL(-ERANGE, co_od_set_i32(od, 0x3101, 0, 0x800000));
	TEST_ASSERT_EQUAL(0, co_od_set_i32(od, 0x3101, 0, -0x800000));
}

static void test_bytes_access(void)
{
	char buf[80];
	uint32_t len;

	TEST_ASSERT_EQUAL(0, co_od_get_bytes(od, 0x1008, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL_UINT32(strlen(FX_DEVICE_NAME), len);
	TEST_ASSERT_EQUAL(-EMSGSIZE, co_od_get_bytes(od, 0x1008, 0, buf, 4, &len));
	TEST_ASSERT_EQUAL_UINT32(27, len);
	TEST_ASSERT_EQUAL(0, co_od_set_bytes(od, FX_IDX_STR, 0, "abcdef", 6));
	TEST_ASSERT_EQUAL_STRING("abcdef", (const char *)co_od_find(od, FX_IDX_STR, 0)->data);
	TEST_ASSERT_EQUAL(0, co_od_set_bytes(od, FX_IDX_STR, 0, "xy", 2));
	TEST_ASSERT_EQUAL_STRING("xy", (const char *)co_od_find(od, FX_IDX_STR, 0)->data);
	memset(buf, 'z', sizeof(buf));
	TEST_ASSERT_EQUAL(-EMSGSIZE, co_od_set_bytes(od, FX_IDX_STR, 0, buf, 65));
	TEST_ASSERT_EQUAL(0, co_od_set_bytes(od, FX_IDX_STR, 0, buf, 64));
	TEST_ASSERT_EQUAL(-EINVAL, co_od_set_bytes(od, 0x1017, 0, buf, 3));
	TEST_ASSERT_EQUAL(0, co_od_set_bytes(od, 0x1017, 0, "\x34\x12", 2));
	uint16_t v;
	co_od_get_u16(od, 0x1017, 0, &v);
	TEST_ASSERT_EQUAL_HEX16(0x1234, v);
}

static void test_check_value_lengths_and_limits(void)
{
	co_od_entry *lim = co_od_find(od, FX_IDX_LIMITED, 0);
	co_od_entry *sgn = co_od_find(od, FX_IDX_SIGNED, 0);
	co_od_entry *str = co_od_find(od, FX_IDX_STR, 0);
	uint8_t d[80] = { 0 };
	co_od_entry *r;

	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_HIGH, co_od_check_value(lim, d, 3));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_LOW, co_od_check_value(lim, d, 1));
	co_put_le16(d, 9);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_LOW, co_od_check_value(lim, d, 2));
	co_put_le16(d, 1001);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH, co_od_check_value(lim, d, 2));
	co_put_le16(d, 10);
	TEST_ASSERT_EQUAL_HEX32(0, co_od_check_value(lim, d, 2));
	co_put_le16(d, (uint16_t)-101);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_LOW, co_od_check_value(sgn, d, 2));
	co_put_le16(d, 101);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH, co_od_check_value(sgn, d, 2));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_HIGH, co_od_check_value(str, d, 65));
	TEST_ASSERT_EQUAL_HEX32(0, co_od_check_value(str, d, 0));

	/* REAL32 limits 0.0 .. 100.0, and NaN */
	TEST_ASSERT_EQUAL(0, co_od_add_num(od, 0x3200, 0, CO_T_REAL32, CO_ACC_RW, 0, &r));
	TEST_ASSERT_EQUAL(0, co_od_entry_set_limits(r, 0x00000000u, 0x42C80000u));
	co_put_le32(d, 0x42C80001u); /* just above 100 */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH, co_od_check_value(r, d, 4));
	co_put_le32(d, 0xBF800000u); /* -1.0 */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_LOW, co_od_check_value(r, d, 4));
	co_put_le32(d, 0x7FC00000u); /* NaN */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, co_od_check_value(r, d, 4));
	co_put_le32(d, 0x3F800000u);
	TEST_ASSERT_EQUAL_HEX32(0, co_od_check_value(r, d, 4));
	TEST_ASSERT_EQUAL(-EINVAL, co_od_entry_set_limits(str, 0, 1));

	/* Limits given in the descriptor; a missing bound = type extreme. */
	int8_t lo = -3;
	co_od_desc desc = {
		.index = 0x3201, .type = CO_T_INTEGER8, .access = CO_ACC_RW, .min = &lo
	};
	TEST_ASSERT_EQUAL(0, co_od_add(od, &desc, &r));
	d[0] = (uint8_t)-4;
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_LOW, co_od_check_value(r, d, 1));
	d[0] = 127;
	TEST_ASSERT_EQUAL_HEX32(0, co_od_check_value(r, d, 1));
}

struct hook_log {
	int checks, afters, reads;
	uint32_t answer;
	co_od_origin origin;
};

static uint32_t h_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct hook_log *l = ctx;
	(void)e;
	l->checks++;
	l->origin = a->origin;
	return l->answer;
}

static void h_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct hook_log *l = ctx;
	(void)e;
	(void)a;
	l->afters++;
}

static const co_od_hooks hooks = { .check_write = h_check, .after_write = h_after };

static void test_write_runs_hooks_and_refusal_keeps_value(void)
{
	struct hook_log l = { .answer = 0x08000022 };
	co_od_entry *e = co_od_find(od, FX_IDX_HOOKED, 0);
	co_od_access a = { .origin = CO_OD_ORIGIN_PDO };
	uint8_t v[4] = { 1, 2, 3, 4 };

	TEST_ASSERT_EQUAL(-ENOENT, co_od_set_hooks(od, 0x2001, 0, &hooks, &l));
	TEST_ASSERT_EQUAL(0, co_od_set_hooks(od, FX_IDX_HOOKED, 0, &hooks, &l));
	TEST_ASSERT_EQUAL_HEX32(0x08000022, co_od_write(e, v, 4, &a));
	TEST_ASSERT_EQUAL_UINT64(7, co_od_entry_raw(e));
	TEST_ASSERT_EQUAL(1, l.checks);
	TEST_ASSERT_EQUAL(0, l.afters);
	TEST_ASSERT_EQUAL(CO_OD_ORIGIN_PDO, l.origin);
	l.answer = 0;
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(e, v, 4, &a));
	TEST_ASSERT_EQUAL_HEX64(0x04030201, co_od_entry_raw(e));
	TEST_ASSERT_EQUAL(1, l.afters);
	/* Length is checked before the hook is asked. */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_LOW, co_od_write(e, v, 3, &a));
	TEST_ASSERT_EQUAL(2, l.checks);
	l.answer = CO_OD_DEFERRED;
	TEST_ASSERT_EQUAL_HEX32(CO_OD_DEFERRED, co_od_write(e, v, 4, &a));
	/* Raw setters bypass hooks. */
	TEST_ASSERT_EQUAL(0, co_od_set_u32(od, FX_IDX_HOOKED, 0, 9));
	TEST_ASSERT_EQUAL(3, l.checks);
}

static void test_reset_ranges_to_defaults(void)
{
	uint16_t v;
	float f;

	co_od_set_u16(od, 0x1017, 0, 4000);
	co_od_set_r32(od, 0x2004, 1, 5.0f);
	co_od_set_bytes(od, FX_IDX_STR, 0, "changed", 7);
	co_od_reset_range(od, 0x1000, 0x1FFF); /* reset communication */
	co_od_get_u16(od, 0x1017, 0, &v);
	TEST_ASSERT_EQUAL_UINT16(1000, v);
	co_od_get_r32(od, 0x2004, 1, &f);
	TEST_ASSERT_EQUAL_FLOAT(5.0f, f);
	co_od_reset_range(od, 0x0000, 0xFFFF); /* reset application */
	co_od_get_r32(od, 0x2004, 1, &f);
	TEST_ASSERT_EQUAL_FLOAT(0.0f, f);
	co_od_entry *s = co_od_find(od, FX_IDX_STR, 0);
	TEST_ASSERT_EQUAL_UINT32(2, s->size);
	TEST_ASSERT_EQUAL_STRING("hi", (const char *)s->data);
	co_od_entry *e = co_od_find(od, 0x1017, 0);
	co_od_entry_set_default_raw(e, 250);
	TEST_ASSERT_EQUAL_UINT64(1000, co_od_entry_raw(e));
	co_od_entry_reset(e);
	TEST_ASSERT_EQUAL_UINT64(250, co_od_entry_raw(e));
}

static void test_array_helper_and_flags(void)
{
	co_od_entry *e;

	TEST_ASSERT_EQUAL(0, co_od_add_array(od, 0x1016, CO_T_UNSIGNED32, 4, CO_ACC_RW, 0));
	e = co_od_find(od, 0x1016, 0);
	TEST_ASSERT_EQUAL(CO_OBJ_ARRAY, e->obj_code);
	TEST_ASSERT_EQUAL_UINT64(4, co_od_entry_raw(e));
	TEST_ASSERT_EQUAL(CO_ACC_RO, e->access);
	TEST_ASSERT_NOT_NULL(co_od_find(od, 0x1016, 4));
	TEST_ASSERT_NULL(co_od_find(od, 0x1016, 5));
	e = co_od_find(od, 0x1017, 0);
	TEST_ASSERT_TRUE(e->access & CO_ACC_PERSIST);
	e = co_od_find(od, 0x2003, 0);
	TEST_ASSERT_TRUE(e->access & CO_ACC_TPDO);
	TEST_ASSERT_FALSE(e->access & CO_ACC_RPDO);
	co_od_desc d = {
		.index = 0x3300, .type = CO_T_UNSIGNED8, .access = CO_ACC_RWW, .name = "Output byte"
	};
	TEST_ASSERT_EQUAL(0, co_od_add(od, &d, &e));
	TEST_ASSERT_EQUAL_STRING("Output byte", e->name);
	TEST_ASSERT_EQUAL(CO_OBJ_VAR, e->obj_code);
}

static void test_crc16_ccitt_check_value(void)
{
	TEST_ASSERT_EQUAL_HEX16(0x31C3, crc16_ccitt(0, "123456789", 9));
	uint16_t c = crc16_ccitt(0, "1234", 4);
	TEST_ASSERT_EQUAL_HEX16(0x31C3, crc16_ccitt(c, "56789", 5));
	TEST_ASSERT_EQUAL_HEX16(0, crc16_ccitt(0, "", 0));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_type_table);
	RUN_TEST(test_every_basic_type_can_be_added);
	RUN_TEST(test_lookup_and_abort_reasons);
	RUN_TEST(test_runtime_add_many_random_order_pointers_stable);
	RUN_TEST(test_typed_get_set);
	RUN_TEST(test_bytes_access);
	RUN_TEST(test_check_value_lengths_and_limits);
	RUN_TEST(test_write_runs_hooks_and_refusal_keeps_value);
	RUN_TEST(test_reset_ranges_to_defaults);
	RUN_TEST(test_array_helper_and_flags);
	RUN_TEST(test_crc16_ccitt_check_value);
	return UNITY_END();
}
