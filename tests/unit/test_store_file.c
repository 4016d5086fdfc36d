/* core/store_file: the seal of saved parameter files (core/store_file.h):
 * every truncation and every flipped bit is found, generations tell a save
 * that was cut between its files. */
#include <errno.h>
#include <string.h>

#include "core/od_image.h"
#include "core/store_file.h"
#include "unity.h"

void setUp(void) {}

void tearDown(void) {}

static const uint8_t image[] = {
	'C',  'O',  'G',  'W',  'O',  'D',  '1',  '\n', 0x17, 0x10, 0x00,
	0x02, 0x00, 0x00, 0x00, 0x90, 0x01,                            /* 1017h:0 = 400 */
	0x00, 0x20, 0x01, 0x04, 0x00, 0x00, 0x00, 1,    2,    3,    4, /* 2000h:1 */
};

static size_t sealed(uint8_t *buf, size_t cap, uint32_t gen, uint32_t set)
{
	memcpy(buf, image, sizeof image);
	long n = co_store_file_seal(buf, sizeof image, cap, gen, set);
	TEST_ASSERT_EQUAL_INT((long)(sizeof image + CO_STORE_FILE_TRAILER), n);
	return (size_t)n;
}

static void test_crc32_check_value(void)
{
	/* the CRC-32 (IEEE) check value of "123456789" */
	TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, co_crc32(0, "123456789", 9));
	/* in pieces = at once */
	TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, co_crc32(co_crc32(0, "1234", 4), "56789", 5));
}

static void test_seal_and_check(void)
{
	uint8_t buf[128];
	co_store_file_info info;
	size_t n = sealed(buf, sizeof buf, 7, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP);

	TEST_ASSERT_EQUAL_INT(0, co_store_file_check(buf, n, &info));
	TEST_ASSERT_EQUAL_UINT32(7, info.generation);
	TEST_ASSERT_EQUAL_UINT32(CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP, info.set);
	TEST_ASSERT_EQUAL_size_t(sizeof image, info.image_len);
	/* the image is untouched and still starts the file */
	TEST_ASSERT_EQUAL_MEMORY(image, buf, sizeof image);
	/* no room for the trailer */
	memcpy(buf, image, sizeof image);
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE,
			      co_store_file_seal(buf, sizeof image, sizeof image + 23, 1, 1));
}

static void test_every_truncation_is_refused(void)
{
	uint8_t buf[128];
	co_store_file_info info;
	size_t n = sealed(buf, sizeof buf, 1, CO_OD_IMAGE_COMM);

	for (size_t cut = 0; cut < n; cut++)
		TEST_ASSERT_NOT_EQUAL_MESSAGE(0, co_store_file_check(buf, cut, &info),
					      "truncated file accepted");
	/* an unsealed image (what older versions wrote) has no trailer */
	TEST_ASSERT_EQUAL_INT(-ENODATA, co_store_file_check(image, sizeof image, &info));
}

static void test_every_bit_flip_is_found(void)
{
	uint8_t buf[128];
	co_store_file_info info;
	size_t n = sealed(buf, sizeof buf, 3, CO_OD_IMAGE_APP);

	for (size_t i = 0; i < n; i++) {
		for (int b = 0; b < 8; b++) {
			buf[i] ^= (uint8_t)(1u << b);
			TEST_ASSERT_NOT_EQUAL_MESSAGE(0, co_store_file_check(buf, n, &info),
						      "flipped bit not found");
			buf[i] ^= (uint8_t)(1u << b);
		}
	}
	TEST_ASSERT_EQUAL_INT(0, co_store_file_check(buf, n, &info));
}

static void test_generations_tell_a_torn_save(void)
{
	const unsigned part[2] = { CO_OD_IMAGE_COMM, CO_OD_IMAGE_APP };
	const uint32_t both = CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP;
	co_store_file_info info[2] = { { 0 } };
	int present[2];

	/* nothing saved, one part saved alone, both saved together */
	present[0] = present[1] = 0;
	TEST_ASSERT_EQUAL_INT(0, co_store_file_torn(info, present, part, 2));
	info[0] = (co_store_file_info){ .generation = 1, .set = CO_OD_IMAGE_COMM };
	present[0] = 1;
	TEST_ASSERT_EQUAL_INT(0, co_store_file_torn(info, present, part, 2));
	info[0] = (co_store_file_info){ .generation = 2, .set = both };
	info[1] = (co_store_file_info){ .generation = 2, .set = both };
	present[0] = present[1] = 1;
	TEST_ASSERT_EQUAL_INT(0, co_store_file_torn(info, present, part, 2));
	/* "save all" cut after the first rename: comm new, app old */
	info[0].generation = 3;
	TEST_ASSERT_EQUAL_INT(1, co_store_file_torn(info, present, part, 2));
	/* ... or the very first save cut: the second file never came */
	present[1] = 0;
	TEST_ASSERT_EQUAL_INT(1, co_store_file_torn(info, present, part, 2));
	/* a later save of comm alone over an older "save all": consistent */
	info[0] = (co_store_file_info){ .generation = 4, .set = CO_OD_IMAGE_COMM };
	info[1] = (co_store_file_info){ .generation = 2, .set = both };
	present[0] = present[1] = 1;
	TEST_ASSERT_EQUAL_INT(0, co_store_file_torn(info, present, part, 2));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_crc32_check_value);
	RUN_TEST(test_seal_and_check);
	RUN_TEST(test_every_truncation_is_refused);
	RUN_TEST(test_every_bit_flip_is_found);
	RUN_TEST(test_generations_tell_a_torn_save);
	return UNITY_END();
}
