/* core/cdcf: concise DCF parser, iterator, OD check and writer. */
#include <errno.h>
#include <string.h>

#include "core/cdcf.h"
#include "unity.h"

void setUp(void) {}

void tearDown(void) {}

/* Two entries: 1017:00 = 1000 (u16), 1800:02 = 0xFE (u8). */
static const uint8_t two[] = {
	0x02, 0x00, 0x00, 0x00, 0x17, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00,
	0xE8, 0x03, 0x00, 0x18, 0x02, 0x01, 0x00, 0x00, 0x00, 0xFE,
};

static co_cdcf_diag check_fail(const uint8_t *b, size_t n)
{
	co_cdcf_diag d;
	uint32_t count = 12345;
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_check(b, n, &count, &d));
	TEST_ASSERT_EQUAL_UINT32(12345, count); /* untouched on failure */
	return d;
}

static void test_parse_two_entries(void)
{
	uint32_t count = 0;
	co_cdcf_diag d;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_check(two, sizeof two, &count, &d));
	TEST_ASSERT_EQUAL_UINT32(2, count);

	co_cdcf_iter it;
	co_cdcf_entry e;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, two, sizeof two, NULL));
	TEST_ASSERT_TRUE(co_cdcf_iter_next(&it, &e));
	TEST_ASSERT_EQUAL_UINT32(1, e.number);
	TEST_ASSERT_EQUAL_HEX16(0x1017, e.index);
	TEST_ASSERT_EQUAL_HEX8(0, e.sub);
	TEST_ASSERT_EQUAL_UINT32(2, e.size);
	TEST_ASSERT_EQUAL_size_t(4, e.offset);
	TEST_ASSERT_EQUAL_HEX8(0xE8, e.data[0]);
	TEST_ASSERT_TRUE(co_cdcf_iter_next(&it, &e));
	TEST_ASSERT_EQUAL_UINT32(2, e.number);
	TEST_ASSERT_EQUAL_HEX16(0x1800, e.index);
	TEST_ASSERT_EQUAL_HEX8(2, e.sub);
	TEST_ASSERT_EQUAL_size_t(13, e.offset);
	TEST_ASSERT_EQUAL_HEX8(0xFE, e.data[0]);
	TEST_ASSERT_FALSE(co_cdcf_iter_next(&it, &e));
	TEST_ASSERT_FALSE(co_cdcf_iter_next(&it, &e));
}

static void test_empty_configuration_is_valid(void)
{
	static const uint8_t zero[] = { 0, 0, 0, 0 };
	uint32_t count = 7;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_check(zero, sizeof zero, &count, NULL));
	TEST_ASSERT_EQUAL_UINT32(0, count);
	co_cdcf_iter it;
	co_cdcf_entry e;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, zero, 4, NULL));
	TEST_ASSERT_FALSE(co_cdcf_iter_next(&it, &e));
}

static void test_no_count(void)
{
	for (size_t n = 0; n < 4; n++) {
		co_cdcf_diag d = check_fail(two, n);
		TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_NO_COUNT, d.error);
		TEST_ASSERT_EQUAL_UINT32(0, d.entry);
		TEST_ASSERT_EQUAL_size_t(n, d.have);
	}
	co_cdcf_diag d = check_fail(NULL, 0);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_NO_COUNT, d.error);
}

static void test_every_truncation_is_named(void)
{
	/* cutting the buffer anywhere inside entry 1 or 2 names that entry */
	for (size_t n = 4; n < sizeof two; n++) {
		co_cdcf_diag d = check_fail(two, n);
		uint32_t want_entry = n < 13 ? 1 : 2;
		size_t entry_at = n < 13 ? 4 : 13;
		TEST_ASSERT_EQUAL_UINT32_MESSAGE(want_entry, d.entry, "entry");
		TEST_ASSERT_EQUAL_UINT32(2, d.count);
		if (n - entry_at < CO_CDCF_HEADER_SIZE) {
			TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_HEADER_TRUNC, d.error);
			TEST_ASSERT_EQUAL_size_t(entry_at, d.offset);
			TEST_ASSERT_EQUAL_size_t(n - entry_at, d.have);
		} else {
			TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_DATA_TRUNC, d.error);
			TEST_ASSERT_EQUAL_size_t(entry_at + 7, d.offset);
			TEST_ASSERT_EQUAL_size_t(n - entry_at - 7, d.have);
			TEST_ASSERT_EQUAL_HEX16(want_entry == 1 ? 0x1017 : 0x1800, d.index);
		}
	}
}

static void test_count_larger_than_entries(void)
{
	uint8_t b[sizeof two];
	memcpy(b, two, sizeof b);
	b[0] = 3;
	co_cdcf_diag d = check_fail(b, sizeof b);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_HEADER_TRUNC, d.error);
	TEST_ASSERT_EQUAL_UINT32(3, d.entry);
	TEST_ASSERT_EQUAL_size_t(sizeof two, d.offset);
	TEST_ASSERT_EQUAL_size_t(0, d.have);

	/* a count near 2^32 over a small buffer fails at once, not after 4e9 steps */
	b[0] = b[1] = b[2] = b[3] = 0xFF;
	d = check_fail(b, sizeof b);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_HEADER_TRUNC, d.error);
	TEST_ASSERT_EQUAL_UINT32(3, d.entry);
	TEST_ASSERT_EQUAL_UINT32(0xFFFFFFFFu, d.count);
}

static void test_count_smaller_than_entries_is_trailing(void)
{
	uint8_t b[sizeof two];
	memcpy(b, two, sizeof b);
	b[0] = 1;
	co_cdcf_diag d = check_fail(b, sizeof b);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_TRAILING, d.error);
	TEST_ASSERT_EQUAL_size_t(13, d.offset);
	TEST_ASSERT_EQUAL_size_t(8, d.have);

	uint8_t c[sizeof two + 1];
	memcpy(c, two, sizeof two);
	c[sizeof two] = 0;
	d = check_fail(c, sizeof c);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_TRAILING, d.error);
	TEST_ASSERT_EQUAL_size_t(sizeof two, d.offset);
	TEST_ASSERT_EQUAL_size_t(1, d.have);
}

static void test_index_zero_and_size_zero(void)
{
	uint8_t b[sizeof two];
	memcpy(b, two, sizeof b);
	b[13] = 0;
	b[14] = 0;
	co_cdcf_diag d = check_fail(b, sizeof b);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_INDEX_ZERO, d.error);
	TEST_ASSERT_EQUAL_UINT32(2, d.entry);
	TEST_ASSERT_EQUAL_size_t(13, d.offset);

	/* size 0 in entry 1 */
	static const uint8_t z[] = { 1, 0, 0, 0, 0x17, 0x10, 0x00, 0, 0, 0, 0 };
	d = check_fail(z, sizeof z);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_SIZE_ZERO, d.error);
	TEST_ASSERT_EQUAL_UINT32(1, d.entry);
	TEST_ASSERT_EQUAL_size_t(7, d.offset);
	TEST_ASSERT_EQUAL_HEX16(0x1017, d.index);
}

static void test_huge_size_does_not_wrap(void)
{
	/* size 0xFFFFFFFF with 2 data bytes: truncated, never an overflowed position */
	static const uint8_t h[] = { 1, 0, 0, 0, 0x00, 0x20, 0x01, 0xFF, 0xFF, 0xFF, 0xFF, 1, 2 };
	co_cdcf_diag d = check_fail(h, sizeof h);
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_DATA_TRUNC, d.error);
	TEST_ASSERT_EQUAL_UINT32(0xFFFFFFFFu, d.size);
	TEST_ASSERT_EQUAL_size_t(2, d.have);
	TEST_ASSERT_EQUAL_HEX8(1, d.sub);
}

static void test_iter_refuses_bad_buffer(void)
{
	co_cdcf_iter it;
	co_cdcf_entry e;
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_iter_init(&it, two, sizeof two - 1, NULL));
	TEST_ASSERT_FALSE(co_cdcf_iter_next(&it, &e));
}

static void test_writer_round_trip_and_measure(void)
{
	uint8_t buf[64];
	co_cdcf_writer w, m;
	uint16_t hb = 1000;
	uint8_t tt = 0xFE;
	co_cdcf_writer_init(&w, buf, sizeof buf);
	co_cdcf_writer_init(&m, NULL, 0);
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_writer_add(&w, 0x1017, 0, &hb, 2));
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_writer_add(&w, 0x1800, 2, &tt, 1));
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_writer_add(&m, 0x1017, 0, &hb, 2));
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_writer_add(&m, 0x1800, 2, &tt, 1));
	TEST_ASSERT_EQUAL_INT((long)sizeof two, co_cdcf_writer_finish(&w));
	TEST_ASSERT_EQUAL_INT((long)sizeof two, co_cdcf_writer_finish(&m));
	TEST_ASSERT_EQUAL_MEMORY(two, buf, sizeof two);
}

static void test_writer_errors_are_sticky(void)
{
	uint8_t buf[14];
	uint32_t v = 1;
	co_cdcf_writer w;
	co_cdcf_writer_init(&w, buf, sizeof buf);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_writer_add(&w, 0, 0, &v, 4));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_writer_finish(&w));

	co_cdcf_writer_init(&w, buf, sizeof buf);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_writer_add(&w, 0x2000, 0, &v, 0));
	co_cdcf_writer_init(&w, buf, sizeof buf);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_writer_add(&w, 0x2000, 0, NULL, 4));

	co_cdcf_writer_init(&w, buf, sizeof buf);
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, co_cdcf_writer_add(&w, 0x2000, 0, &v, 4)); /* needs 15 */
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, co_cdcf_writer_add(&w, 0x2000, 0, &v, 1));
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, co_cdcf_writer_finish(&w));

	co_cdcf_writer_init(&w, buf, 3);
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, co_cdcf_writer_finish(&w));
}

static co_od *make_od(void)
{
	co_od *od = NULL;
	co_od_entry *lim = NULL;
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&od, 8));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x1017, 0, CO_T_UNSIGNED16, CO_ACC_RW, 0, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, 0, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x1800, 2, CO_T_UNSIGNED8, CO_ACC_RW, 0, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x2000, 0, CO_T_UNSIGNED8, CO_ACC_RW, 5, &lim));
	TEST_ASSERT_EQUAL_INT(0, co_od_entry_set_limits(lim, 1, 10));
	return od;
}

static long one_entry(uint8_t *buf, size_t cap, uint16_t index, uint8_t sub, const void *data,
		      uint32_t size)
{
	co_cdcf_writer w;
	co_cdcf_writer_init(&w, buf, cap);
	co_cdcf_writer_add(&w, index, sub, data, size);
	return co_cdcf_writer_finish(&w);
}

static void test_check_against_od(void)
{
	co_od *od = make_od();
	co_cdcf_diag d;
	uint8_t buf[32];
	uint32_t u32 = 0;
	uint8_t u8 = 20;
	long n;
	char text[160];

	TEST_ASSERT_EQUAL_INT(0, co_cdcf_check_od(two, sizeof two, od, false, &d));

	n = one_entry(buf, sizeof buf, 0x1017, 0, &u32, 4);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_check_od(buf, (size_t)n, od, false, &d));
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_SIZE_MISMATCH, d.error);
	TEST_ASSERT_EQUAL_HEX32(0x06070012, d.abort);
	co_cdcf_diag_format(&d, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING("entry 1 (1017:00, size 4) at byte 7: size does not match the "
				 "data type (abort 06070012)",
				 text);

	n = one_entry(buf, sizeof buf, 0x1017, 1, &u32, 2);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_check_od(buf, (size_t)n, od, false, &d));
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_NO_SUB, d.error);
	n = one_entry(buf, sizeof buf, 0x6000, 0, &u32, 2);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_check_od(buf, (size_t)n, od, false, &d));
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_NO_OBJECT, d.error);
	TEST_ASSERT_EQUAL_HEX32(0x06020000, d.abort);

	n = one_entry(buf, sizeof buf, 0x1000, 0, &u32, 4);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_check_od(buf, (size_t)n, od, false, &d));
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_READ_ONLY, d.error);
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_check_od(buf, (size_t)n, od, true, &d));

	n = one_entry(buf, sizeof buf, 0x2000, 0, &u8, 1);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cdcf_check_od(buf, (size_t)n, od, false, &d));
	TEST_ASSERT_EQUAL_INT(CO_CDCF_ERR_VALUE, d.error);
	TEST_ASSERT_EQUAL_HEX32(0x06090031, d.abort);
	co_od_destroy(od);
}

static void test_diag_texts(void)
{
	char text[160];
	co_cdcf_diag d;

	check_fail(two, 2);
	d = check_fail(two, 2);
	co_cdcf_diag_format(&d, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING("at byte 0: no entry count (fewer than 4 bytes): 2 bytes", text);
	d = check_fail(two, 8);
	co_cdcf_diag_format(&d, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING(
		"entry 1 of 2 at byte 4: entry header cut short (4 of 7 header bytes)", text);
	d = check_fail(two, 20);
	co_cdcf_diag_format(&d, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING(
		"entry 2 of 2 (1800:02) at byte 20: data cut short (size 1, 0 bytes left)", text);
	uint8_t c[sizeof two + 3];
	memcpy(c, two, sizeof two);
	d = check_fail(c, sizeof c);
	co_cdcf_diag_format(&d, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING("at byte 21: 3 bytes after the last counted entry (count 2)",
				 text);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_parse_two_entries);
	RUN_TEST(test_empty_configuration_is_valid);
	RUN_TEST(test_no_count);
	RUN_TEST(test_every_truncation_is_named);
	RUN_TEST(test_count_larger_than_entries);
	RUN_TEST(test_count_smaller_than_entries_is_trailing);
	RUN_TEST(test_index_zero_and_size_zero);
	RUN_TEST(test_huge_size_does_not_wrap);
	RUN_TEST(test_iter_refuses_bad_buffer);
	RUN_TEST(test_writer_round_trip_and_measure);
	RUN_TEST(test_writer_errors_are_sticky);
	RUN_TEST(test_check_against_od);
	RUN_TEST(test_diag_texts);
	return UNITY_END();
}
