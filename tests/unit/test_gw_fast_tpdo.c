/* SPDX-License-Identifier: MIT */
/*
 * The fast TPDOs of PDO forwarding (gateway/fast_tpdo.h): the frame a
 * source builds from the image, the gate both senders share (inhibit
 * time), the busy word (no overtaking of a held update), closing, and the
 * core's side of the gate. One thread here; tests/tsan/test_gw_fast_stress
 * runs the two sides on two threads.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "gateway/fast_tpdo.h"

static gw_image *img;
static gw_fast F;

struct sent_log {
	unsigned n;
	co_frame last;
	int fail; /* next send's answer */
};
static struct sent_log sent;

static int capture(void *ctx, const co_frame *f)
{
	struct sent_log *s = ctx;

	if (s->fail)
		return s->fail;
	s->n++;
	s->last = *f;
	return 0;
}

void setUp(void)
{
	TEST_ASSERT_EQUAL(0, gw_image_create(&img, 8));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 0, 4, 0x11223344));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB001, 0, 1, 0x01));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB002, 0, 2, 0xBEEF));
	/* as gateway.forward's image objects: UNSIGNED64, values sign-extended */
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xBF00, 0, 8, 0));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xBF01, 0, 8, 0));
	gw_image_seal(img);
	TEST_ASSERT_EQUAL(0, gw_fast_init(&F, gw_image_count(img)));
	gw_fast_set_carrying(&F, true);
	memset(&sent, 0, sizeof(sent));
}

void tearDown(void)
{
	gw_fast_fini(&F);
	gw_image_destroy(img);
}

static gw_fast_desc desc_u32(uint16_t nr, uint32_t id, uint32_t inhibit_us)
{
	gw_fast_desc d = { .nr = nr, .can_id = id, .len = 4, .n = 1, .inhibit_us = inhibit_us };

	d.map[0] = (uint32_t)gw_image_find(img, 0xB000, 0) << 8 | 32;
	return d;
}

static void publish(const gw_fast_desc *d, unsigned n)
{
	uint64_t until[4] = { 0 };
	bool pending[4] = { false };

	TEST_ASSERT_EQUAL(n, gw_fast_publish(&F, d, until, pending, n, NULL));
}

static uint32_t try_at(int slot, uint64_t now, uint32_t *held)
{
	uint16_t nr[GW_FAST_SENT_MAX];

	return gw_fast_try(&F, img, slot, now, capture, &sent, held, nr);
}

static void test_frame_carries_cob_id_and_image_value(void)
{
	gw_fast_desc d = desc_u32(1, 0x1FF, 0);
	int slot = gw_image_find(img, 0xB000, 0);
	uint32_t held;

	publish(&d, 1);
	gw_image_write(img, slot, 0xCAFEF00D);
	TEST_ASSERT_EQUAL_HEX32(1, try_at(slot, 1000, &held));
	TEST_ASSERT_EQUAL_HEX32(0, held);
	TEST_ASSERT_EQUAL(1, sent.n);
	TEST_ASSERT_EQUAL_HEX32(0x1FF, sent.last.id);
	TEST_ASSERT_EQUAL(4, sent.last.len);
	TEST_ASSERT_EQUAL_HEX8(0x0D, sent.last.data[0]);
	TEST_ASSERT_EQUAL_HEX8(0xF0, sent.last.data[1]);
	TEST_ASSERT_EQUAL_HEX8(0xFE, sent.last.data[2]);
	TEST_ASSERT_EQUAL_HEX8(0xCA, sent.last.data[3]);
	/* a slot no fast TPDO maps: nothing to do, nothing held */
	TEST_ASSERT_EQUAL(0, try_at(gw_image_find(img, 0xB002, 0), 1000, &held));
	TEST_ASSERT_EQUAL(0, held);
}

/* Entries packed LSB first in mapping order, each the low bits of its
 * object (as core/pdo_map.c packs a TPDO): 1 bit of B001h, 16 bits of
 * B002h, 8 bits of B000h. */
static void test_bit_packing_follows_the_mapping(void)
{
	gw_fast_desc d = { .nr = 2, .can_id = 0x2AB, .len = 4, .n = 3 };
	uint32_t held;

	d.map[0] = (uint32_t)gw_image_find(img, 0xB001, 0) << 8 | 1;
	d.map[1] = (uint32_t)gw_image_find(img, 0xB002, 0) << 8 | 16;
	d.map[2] = (uint32_t)gw_image_find(img, 0xB000, 0) << 8 | 8;
	publish(&d, 1);
	TEST_ASSERT_EQUAL_HEX32(1, try_at(gw_image_find(img, 0xB002, 0), 10, &held));
	/* 1 | 0xBEEF << 1 | 0x44 << 17 = 0x0089_7DDF */
	TEST_ASSERT_EQUAL_HEX8(0xDF, sent.last.data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x7D, sent.last.data[1]);
	TEST_ASSERT_EQUAL_HEX8(0x89, sent.last.data[2]);
	TEST_ASSERT_EQUAL_HEX8(0x00, sent.last.data[3]);
}

/* A device object's frame (fit): a value its entry cannot hold is not
 * sent - the owner takes it and refuses it; one that fits goes, as its
 * low bits. Signed entries hold the image's sign-extended integer. */
static void test_values_that_do_not_fit_are_left_to_the_owner(void)
{
	gw_fast_desc d = { .nr = 3, .can_id = 0x209, .len = 2, .n = 2, .fit = 1 };
	int u8 = gw_image_find(img, 0xBF00, 0), s8 = gw_image_find(img, 0xBF01, 0);
	uint32_t held;

	d.map[0] = (uint32_t)u8 << 8 | 8;
	d.map[1] = (uint32_t)s8 << 8 | 8 | GW_FAST_MAP_SIGNED;
	publish(&d, 1);
	gw_image_write(img, u8, 300); /* UNSIGNED8: 300 does not fit */
	gw_image_write(img, s8, UINT64_MAX);
	TEST_ASSERT_EQUAL(0, try_at(u8, 10, &held));
	TEST_ASSERT_EQUAL(0, sent.n);
	TEST_ASSERT_EQUAL_HEX32(1, held);
	gw_image_write(img, u8, 255);
	gw_image_write(img, s8, (uint64_t)-129); /* INTEGER8: -129 does not fit */
	TEST_ASSERT_EQUAL(0, try_at(s8, 20, &held));
	gw_image_write(img, s8, (uint64_t)-128);
	TEST_ASSERT_EQUAL_HEX32(1, try_at(s8, 30, &held));
	TEST_ASSERT_EQUAL(1, sent.n);
	TEST_ASSERT_EQUAL_HEX8(0xFF, sent.last.data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x80, sent.last.data[1]);
}

static void test_inhibit_time_is_shared_by_both_senders(void)
{
	gw_fast_desc d = desc_u32(1, 0x1FF, 1000);
	int slot = gw_image_find(img, 0xB000, 0);
	uint32_t held;

	publish(&d, 1);
	TEST_ASSERT_EQUAL(1, try_at(slot, 5000, &held));
	/* inside the inhibit time: the source hands off and holds */
	TEST_ASSERT_EQUAL(0, try_at(slot, 5500, &held));
	TEST_ASSERT_EQUAL_HEX32(1, held);
	/* the owner's core, at 5600, must wait until 6000 */
	TEST_ASSERT_EQUAL_UINT64(6000, gw_fast_gate(&F, 1, CO_PDO_GATE_CLAIM, 5600));
	/* its event now waits: no source frame may come between */
	TEST_ASSERT_EQUAL(0, try_at(slot, 6100, &held));
	TEST_ASSERT_EQUAL(1, sent.n);
	/* the owner sends at 6000; the gate runs to 7000 */
	TEST_ASSERT_EQUAL_UINT64(CO_PDO_GATE_GO, gw_fast_gate(&F, 1, CO_PDO_GATE_CLAIM, 6000));
	TEST_ASSERT_EQUAL(0, try_at(slot, 6999, &held));
	TEST_ASSERT_EQUAL(1, try_at(slot, 7000, &held));
	TEST_ASSERT_EQUAL(2, sent.n);
	/* a forced transmission (RTR) moves the gate too */
	gw_fast_gate(&F, 1, CO_PDO_GATE_FORCED, 8000);
	TEST_ASSERT_EQUAL(0, try_at(slot, 8500, &held));
	TEST_ASSERT_EQUAL(1, try_at(slot, 9000, &held));
}

static void test_held_update_is_not_overtaken(void)
{
	gw_fast_desc d = desc_u32(1, 0x1FF, 0);
	int slot = gw_image_find(img, 0xB000, 0);
	uint32_t held;

	publish(&d, 1);
	gw_fast_set_carrying(&F, false); /* the target is busy */
	TEST_ASSERT_EQUAL(0, try_at(slot, 100, &held));
	TEST_ASSERT_EQUAL_HEX32(1, held);
	gw_fast_hold(&F, held); /* the update is in the ring */
	gw_fast_set_carrying(&F, true);
	TEST_ASSERT_EQUAL(0, try_at(slot, 200, &held));
	gw_fast_hold(&F, held);
	/* the owner applied the first, then the second */
	gw_fast_taken(&F, 1, true);
	TEST_ASSERT_EQUAL(0, try_at(slot, 300, &held));
	gw_fast_hold(&F, held);
	gw_fast_taken(&F, 1, true);
	gw_fast_taken(&F, 1, true);
	TEST_ASSERT_EQUAL(1, try_at(slot, 400, &held));
	TEST_ASSERT_EQUAL(1, sent.n);
	/* applied while the owner's transmit queue held frames: its frame
	 * may still be queued, so the update stays busy until the queue is
	 * empty again */
	gw_fast_hold(&F, 1);
	gw_fast_taken(&F, 1, false);
	TEST_ASSERT_EQUAL(0, try_at(slot, 600, &held));
	gw_fast_set_carrying(&F, true);
	TEST_ASSERT_EQUAL(1, try_at(slot, 700, &held));
	/* a hand-off that failed takes its hold back */
	gw_fast_hold(&F, 1);
	gw_fast_undo_hold(&F, 1);
	TEST_ASSERT_EQUAL(1, try_at(slot, 800, &held));
}

static void test_closed_and_retired_tpdos_are_handed_off(void)
{
	gw_fast_desc d = desc_u32(1, 0x1FF, 0);
	int slot = gw_image_find(img, 0xB000, 0);
	uint32_t held;

	publish(&d, 1);
	gw_fast_gate(&F, 1, CO_PDO_GATE_RESET, 50); /* e.g. the node left OPERATIONAL */
	TEST_ASSERT_EQUAL(0, try_at(slot, 100, &held));
	TEST_ASSERT_EQUAL_HEX32(1, held);
	publish(&d, 1); /* back */
	TEST_ASSERT_EQUAL(1, try_at(slot, 200, &held));
	publish(NULL, 0); /* no longer a fast TPDO (made synchronous) */
	TEST_ASSERT_EQUAL(0, try_at(slot, 300, &held));
	TEST_ASSERT_EQUAL(0, held);
	TEST_ASSERT_EQUAL_UINT64(CO_PDO_GATE_GO, gw_fast_gate(&F, 1, CO_PDO_GATE_CLAIM, 300));
	TEST_ASSERT_EQUAL(0, gw_fast_nr(&F, 0));
	TEST_ASSERT_EQUAL(1, sent.n);
}

static void test_republication_changes_the_frame(void)
{
	gw_fast_desc d = desc_u32(1, 0x1FF, 0);
	int slot = gw_image_find(img, 0xB000, 0);
	uint32_t held;

	publish(&d, 1);
	TEST_ASSERT_EQUAL(1, try_at(slot, 100, &held));
	d.can_id = 0x2FF;
	d.len = 2;
	d.map[0] = (uint32_t)slot << 8 | 16;
	publish(&d, 1);
	TEST_ASSERT_EQUAL(1, try_at(slot, 200, &held));
	TEST_ASSERT_EQUAL_HEX32(0x2FF, sent.last.id);
	TEST_ASSERT_EQUAL(2, sent.last.len);
	TEST_ASSERT_EQUAL_HEX8(0x44, sent.last.data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x33, sent.last.data[1]);
}

static void test_failed_send_gives_the_gate_back(void)
{
	gw_fast_desc d = desc_u32(1, 0x1FF, 1000);
	int slot = gw_image_find(img, 0xB000, 0);
	uint32_t held;

	publish(&d, 1);
	sent.fail = -ENETDOWN;
	TEST_ASSERT_EQUAL(0, try_at(slot, 100, &held));
	TEST_ASSERT_EQUAL_HEX32(1, held);
	sent.fail = 0;
	/* nothing left: no inhibit time runs */
	TEST_ASSERT_EQUAL_UINT64(CO_PDO_GATE_GO, gw_fast_gate(&F, 1, CO_PDO_GATE_CLAIM, 150));
}

static void test_served_while_applying_what_a_source_sent(void)
{
	gw_fast_desc d = desc_u32(4, 0x1FF, 0);
	uint32_t held;

	publish(&d, 1);
	TEST_ASSERT_EQUAL(1, try_at(gw_image_find(img, 0xB000, 0), 100, &held));
	static const uint16_t sent_nr[] = { 4 };
	F.serving_nr = sent_nr;
	F.n_serving = 1;
	TEST_ASSERT_EQUAL_UINT64(CO_PDO_GATE_SERVED, gw_fast_gate(&F, 4, CO_PDO_GATE_CLAIM, 100));
	/* inside the inhibit time that frame started: dropped, not waiting */
	TEST_ASSERT_EQUAL_UINT64(CO_PDO_GATE_SERVED, gw_fast_gate(&F, 4, CO_PDO_GATE_WAIT, 100));
	TEST_ASSERT_EQUAL_HEX32(0, atomic_load(&F.t[0].busy));
	F.n_serving = 0;
	/* reset by the core (reconfigured, NMT): closed at once, stale */
	TEST_ASSERT_FALSE(F.stale);
	gw_fast_gate(&F, 4, CO_PDO_GATE_RESET, 200);
	TEST_ASSERT_TRUE(F.stale);
	TEST_ASSERT_EQUAL(0, try_at(gw_image_find(img, 0xB000, 0), 300, &held));
	TEST_ASSERT_EQUAL_HEX32(1, held);
	publish(&d, 1);
	TEST_ASSERT_FALSE(F.stale);
	TEST_ASSERT_EQUAL(1, try_at(gw_image_find(img, 0xB000, 0), 300, &held));
	/* a TPDO that is not fast is never held back by the gate */
	TEST_ASSERT_EQUAL_UINT64(CO_PDO_GATE_GO, gw_fast_gate(&F, 5, CO_PDO_GATE_CLAIM, 100));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_frame_carries_cob_id_and_image_value);
	RUN_TEST(test_bit_packing_follows_the_mapping);
	RUN_TEST(test_values_that_do_not_fit_are_left_to_the_owner);
	RUN_TEST(test_inhibit_time_is_shared_by_both_senders);
	RUN_TEST(test_held_update_is_not_overtaken);
	RUN_TEST(test_closed_and_retired_tpdos_are_handed_off);
	RUN_TEST(test_republication_changes_the_frame);
	RUN_TEST(test_failed_send_gives_the_gate_back);
	RUN_TEST(test_served_while_applying_what_a_source_sent);
	return UNITY_END();
}
