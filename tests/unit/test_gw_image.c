/* SPDX-License-Identifier: MIT */
/*
 * The shared process image B000h..BFFFh (gateway/image.h): slots, lookups,
 * byte order, no torn 8-byte values between threads, and the per-line
 * forwarding lists rebuilt from the TPDO mappings of an OD.
 */
#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <string.h>

#include "unity.h"

#include "core/od.h"
#include "core/pdo.h"
#include "gateway/image.h"

static gw_image *img;

void setUp(void)
{
	TEST_ASSERT_EQUAL(0, gw_image_create(&img, 8));
}

void tearDown(void)
{
	gw_image_destroy(img);
	img = NULL;
}

static void test_slots_and_lookup(void)
{
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB001, 0, 8, 0));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 0, 4, 0x1234567890ULL));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 2, 2, 7));
	TEST_ASSERT_EQUAL(-EEXIST, gw_image_add(img, 0xB000, 2, 2, 7));
	TEST_ASSERT_EQUAL(-EINVAL, gw_image_add(img, 0xA000, 0, 2, 0));
	TEST_ASSERT_EQUAL(-EINVAL, gw_image_add(img, 0xC000, 0, 2, 0));
	TEST_ASSERT_EQUAL(-EINVAL, gw_image_add(img, 0xB002, 0, 9, 0));
	TEST_ASSERT_EQUAL(-EINVAL, gw_image_add(img, 0xB002, 0, 0, 0));
	TEST_ASSERT_EQUAL(-ENOENT, gw_image_find(img, 0xB000, 0)); /* not sealed */
	gw_image_seal(img);
	TEST_ASSERT_EQUAL(-EPERM, gw_image_add(img, 0xB003, 0, 1, 0));
	TEST_ASSERT_EQUAL(3, gw_image_count(img));
	TEST_ASSERT_EQUAL(0, gw_image_find(img, 0xB000, 0));
	TEST_ASSERT_EQUAL(1, gw_image_find(img, 0xB000, 2));
	TEST_ASSERT_EQUAL(2, gw_image_find(img, 0xB001, 0));
	TEST_ASSERT_EQUAL(-ENOENT, gw_image_find(img, 0xB000, 1));
	/* the initial value is cut to the object's size */
	TEST_ASSERT_EQUAL_HEX64(0x34567890, gw_image_read(img, 0));
	TEST_ASSERT_EQUAL(4, gw_image_slot_at(img, 0)->size);
	TEST_ASSERT_NULL(gw_image_slot_at(img, 3));
}

static void test_bytes_round_trip(void)
{
	uint8_t in[8] = { 1, 2, 3, 4, 5, 6, 7, 8 }, out[8] = { 0 };
	uint64_t b;

	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 0, 8, 0));
	gw_image_seal(img);
	b = gw_image_bits_from(in, 8);
	TEST_ASSERT_EQUAL_HEX64(0x0807060504030201ULL, b);
	gw_image_write(img, 0, b);
	gw_image_bits_to(gw_image_read(img, 0), out, 8);
	TEST_ASSERT_EQUAL_MEMORY(in, out, 8);
	TEST_ASSERT_EQUAL_HEX64(0x0201, gw_image_bits_from(in, 2));
	TEST_ASSERT_EQUAL_UINT64(1, atomic_load(&gw_image_slot_at(img, 0)->writes));
}

/* Two writers publish values whose halves are equal (hi32 == lo32, from
 * distinct sequences); a reader checks every value it sees. A torn read
 * would pair the halves of two different values. */
#define TORN_ROUNDS 200000u

static atomic_bool torn_stop;

static void *torn_writer(void *arg)
{
	uint32_t base = (uint32_t)(uintptr_t)arg;

	for (uint32_t i = 0; i < TORN_ROUNDS; i++) {
		uint32_t v = base + i * 2u;
		gw_image_write(img, 0, (uint64_t)v << 32 | v);
	}
	return NULL;
}

static void *torn_reader(void *arg)
{
	unsigned *bad = arg;

	while (!atomic_load(&torn_stop)) {
		uint64_t v = gw_image_read(img, 0);
		if ((uint32_t)v != (uint32_t)(v >> 32))
			(*bad)++;
	}
	return NULL;
}

static void test_no_torn_values_between_threads(void)
{
	pthread_t w1, w2, r;
	unsigned bad = 0;

	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 0, 8, 0));
	gw_image_seal(img);
	atomic_store(&torn_stop, false);
	TEST_ASSERT_EQUAL(0, pthread_create(&r, NULL, torn_reader, &bad));
	TEST_ASSERT_EQUAL(0, pthread_create(&w1, NULL, torn_writer, (void *)(uintptr_t)1));
	TEST_ASSERT_EQUAL(0,
			  pthread_create(&w2, NULL, torn_writer, (void *)(uintptr_t)0x40000000u));
	pthread_join(w1, NULL);
	pthread_join(w2, NULL);
	atomic_store(&torn_stop, true);
	pthread_join(r, NULL);
	TEST_ASSERT_EQUAL_UINT(0, bad);
	TEST_ASSERT_EQUAL_UINT64(2 * TORN_ROUNDS, atomic_load(&gw_image_slot_at(img, 0)->writes));
}

static void add_tpdo(co_od *od, uint16_t nr, bool valid, uint8_t n_map, const uint32_t *map)
{
	co_pdo_desc d = { .dir = CO_PDO_TX,
			  .nr = nr,
			  .cob_id = (valid ? 0 : CO_PDO_COB_INVALID) | (0x180u + nr),
			  .tt = 255,
			  .n_map = n_map,
			  .map = map };
	TEST_ASSERT_EQUAL(0, co_od_add_pdo(od, &d));
}

static void test_forwarding_list_follows_the_tpdo_mapping(void)
{
	co_od *od;
	gw_fwd_list l;
	uint32_t m1[] = { CO_PDO_MAP(0xB000, 0, 32), CO_PDO_MAP(0x2000, 0, 16) };
	uint32_t m2[] = { CO_PDO_MAP(0xB001, 0, 64) };
	uint32_t m3[] = { CO_PDO_MAP(0xB002, 1, 8), CO_PDO_MAP(0xB000, 0, 32) };

	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 0, 4, 0));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB001, 0, 8, 0));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB002, 1, 1, 0));
	gw_image_seal(img);
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 64));
	add_tpdo(od, 1, true, 2, m1);
	add_tpdo(od, 2, false, 1, m2); /* invalid: not in the list */
	add_tpdo(od, 7, true, 2, m3);
	TEST_ASSERT_EQUAL(0, gw_fwd_list_init(&l, img));
	TEST_ASSERT_FALSE(gw_fwd_list_has(&l, 0));
	TEST_ASSERT_EQUAL(2, gw_fwd_list_rebuild(&l, img, od));
	TEST_ASSERT_TRUE(gw_fwd_list_has(&l, gw_image_find(img, 0xB000, 0)));
	TEST_ASSERT_FALSE(gw_fwd_list_has(&l, gw_image_find(img, 0xB001, 0)));
	TEST_ASSERT_TRUE(gw_fwd_list_has(&l, gw_image_find(img, 0xB002, 1)));
	TEST_ASSERT_FALSE(gw_fwd_list_has(&l, -1));
	TEST_ASSERT_FALSE(gw_fwd_list_has(&l, 1000));

	/* remap: TPDO 2 validated, TPDO 7 emptied (sub 0 = 0) */
	TEST_ASSERT_EQUAL(0, co_od_set_u32(od, 0x1801, 1, 0x182));
	TEST_ASSERT_EQUAL(0, co_od_set_u8(od, 0x1A06, 0, 0));
	TEST_ASSERT_EQUAL(2, gw_fwd_list_rebuild(&l, img, od));
	TEST_ASSERT_TRUE(gw_fwd_list_has(&l, gw_image_find(img, 0xB001, 0)));
	TEST_ASSERT_FALSE(gw_fwd_list_has(&l, gw_image_find(img, 0xB002, 1)));
	TEST_ASSERT_EQUAL(2, l.rebuilds);
	gw_fwd_list_fini(&l);
	co_od_destroy(od);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_slots_and_lookup);
	RUN_TEST(test_bytes_round_trip);
	RUN_TEST(test_no_torn_values_between_threads);
	RUN_TEST(test_forwarding_list_follows_the_tpdo_mapping);
	return UNITY_END();
}
