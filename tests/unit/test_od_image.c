/* core/od_image: the byte image behind 1010h "save" (daemon and simulator). */
#include <errno.h>
#include <string.h>

#include "core/frame.h"
#include "core/od_image.h"
#include "unity.h"

static co_od *od;

void setUp(void)
{
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&od, 16));
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_add_num(od, 0x1017, 0, CO_T_UNSIGNED16, CO_ACC_RW, 1000, NULL));
	TEST_ASSERT_EQUAL_INT(
		0, co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_CO, 0x40194, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x1010, 1, CO_T_UNSIGNED32, CO_ACC_RW, 1, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_bytes(od, 0x2001, 0, CO_T_VISIBLE_STRING, CO_ACC_RW, 32,
						 "abc", 3, NULL));
	co_od_entry *lim = NULL;
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x2002, 0, CO_T_UNSIGNED8, CO_ACC_RW, 5, &lim));
	TEST_ASSERT_EQUAL_INT(0, co_od_entry_set_limits(lim, 1, 10));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x2003, 0, CO_T_UNSIGNED8, CO_ACC_RO, 7, NULL));
}

void tearDown(void)
{
	co_od_destroy(od);
}

static void test_round_trip_restores_values_and_defaults(void)
{
	uint8_t img[256];
	co_od_set_u16(od, 0x1017, 0, 4000);
	co_od_set_bytes(od, 0x2001, 0, "changed", 7);
	co_od_set_u8(od, 0x2002, 0, 9);
	long n = co_od_image_write(od, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP, img, sizeof img);
	TEST_ASSERT_TRUE(n > (long)CO_OD_IMAGE_MAGIC_LEN);

	co_od_reset_range(od, 0x0000, 0xFFFF);
	uint16_t hb = 0;
	co_od_get_u16(od, 0x1017, 0, &hb);
	TEST_ASSERT_EQUAL_UINT16(1000, hb);

	unsigned applied, skipped;
	TEST_ASSERT_EQUAL_INT(0, co_od_image_apply(od, img, (size_t)n,
						   CO_OD_IMAGE_SET_VALUE | CO_OD_IMAGE_SET_DEFAULT,
						   &applied, &skipped));
	TEST_ASSERT_EQUAL_UINT(3, applied);
	TEST_ASSERT_EQUAL_UINT(0, skipped);
	co_od_get_u16(od, 0x1017, 0, &hb);
	TEST_ASSERT_EQUAL_UINT16(4000, hb);
	char s[32];
	uint32_t len = 0;
	co_od_get_bytes(od, 0x2001, 0, s, sizeof s, &len);
	TEST_ASSERT_EQUAL_UINT32(7, len);
	TEST_ASSERT_EQUAL_MEMORY("changed", s, 7);
	/* loaded values became the defaults: a reset keeps them */
	co_od_reset_range(od, 0x0000, 0xFFFF);
	co_od_get_u16(od, 0x1017, 0, &hb);
	TEST_ASSERT_EQUAL_UINT16(4000, hb);
}

static void test_parts_and_what_is_left_out(void)
{
	uint8_t img[256];
	long comm = co_od_image_write(od, CO_OD_IMAGE_COMM, img, sizeof img);
	/* only 1017h: 1000h is constant, 1010h is the store command itself */
	TEST_ASSERT_EQUAL_INT(CO_OD_IMAGE_MAGIC_LEN + 7 + 2, comm);
	TEST_ASSERT_EQUAL_HEX8(0x17, img[8]);
	TEST_ASSERT_EQUAL_HEX8(0x10, img[9]);
	long app = co_od_image_write(od, CO_OD_IMAGE_APP, img, sizeof img);
	TEST_ASSERT_EQUAL_INT(CO_OD_IMAGE_MAGIC_LEN + 7 + 3 + 7 + 1,
			      app); /* 2001h, 2002h; not ro 2003h */
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, co_od_image_write(od, CO_OD_IMAGE_APP, img, 12));
}

static void test_bad_records_are_skipped_not_trusted(void)
{
	uint8_t img[256];
	long n = co_od_image_write(od, CO_OD_IMAGE_APP, img, sizeof img);
	/* 2002h out of its limits 1..10, and a record for a missing object */
	img[n - 1] = 200;
	const uint8_t missing[] = { 0x99, 0x20, 0x00, 1, 0, 0, 0, 42 };
	memcpy(img + n, missing, sizeof missing);
	n += (long)sizeof missing;
	unsigned applied, skipped;
	TEST_ASSERT_EQUAL_INT(0, co_od_image_apply(od, img, (size_t)n, CO_OD_IMAGE_SET_VALUE,
						   &applied, &skipped));
	TEST_ASSERT_EQUAL_UINT(1, applied);
	TEST_ASSERT_EQUAL_UINT(2, skipped);
	uint8_t v = 0;
	co_od_get_u8(od, 0x2002, 0, &v);
	TEST_ASSERT_EQUAL_UINT8(5, v);

	/* truncated tail: what came before is kept, the rest counted once */
	n = co_od_image_write(od, CO_OD_IMAGE_APP, img, sizeof img);
	TEST_ASSERT_EQUAL_INT(0, co_od_image_apply(od, img, (size_t)n - 3, CO_OD_IMAGE_SET_VALUE,
						   &applied, &skipped));
	TEST_ASSERT_EQUAL_UINT(1, applied);
	TEST_ASSERT_EQUAL_UINT(1, skipped);
	/* a record that claims to be longer than the buffer */
	co_put_le32(img + 8 + 3, 0xFFFFFFF0u);
	TEST_ASSERT_EQUAL_INT(0, co_od_image_apply(od, img, (size_t)n, CO_OD_IMAGE_SET_VALUE,
						   &applied, &skipped));
	TEST_ASSERT_EQUAL_UINT(0, applied);
	TEST_ASSERT_EQUAL_UINT(1, skipped);
}

static void test_foreign_data_is_refused_whole(void)
{
	const uint8_t junk[] = "not an image at all";
	unsigned applied, skipped;
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      co_od_image_apply(od, junk, sizeof junk, CO_OD_IMAGE_SET_VALUE,
						&applied, &skipped));
	TEST_ASSERT_EQUAL_INT(
		-EINVAL, co_od_image_apply(od, junk, 3, CO_OD_IMAGE_SET_VALUE, &applied, &skipped));
	TEST_ASSERT_EQUAL_UINT(0, applied);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_round_trip_restores_values_and_defaults);
	RUN_TEST(test_parts_and_what_is_left_out);
	RUN_TEST(test_bad_records_are_skipped_not_trusted);
	RUN_TEST(test_foreign_data_is_refused_whole);
	return UNITY_END();
}
