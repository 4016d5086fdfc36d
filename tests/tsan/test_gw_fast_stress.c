/* SPDX-License-Identifier: MIT */
/*
 * Stress of the fast TPDOs of PDO forwarding (gateway/fast_tpdo.c) under
 * ThreadSanitizer: two source threads write B-objects and send the target's
 * TPDO themselves when its gate lets them, the owner thread claims the
 * same gate for its own transmissions, applies the sources' hand-offs
 * (real lines/xring.c rings) and republishes the TPDO with another
 * COB-ID and mapping now and then, or closes it.
 *
 * Checked:
 * - no data race (TSan fails the run on one);
 * - the inhibit time: all transmissions of both sides, in time order, are
 *   at least the inhibit time apart;
 * - no frame mixes two publications: COB-ID 181h always carries B000h's
 *   value, 182h B001h's (each self-checking: high half = ~low half, and a
 *   tag bit telling the objects apart);
 * - the busy count returns to 0 once every hand-off is applied;
 * - both sides did send (the run exercised the race).
 */
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "unity.h"

#include "gateway/fast_tpdo.h"
#include "lines/xring.h"

#define SOURCES 2u
#define WRITES 40000u
#define INHIBIT_US 50u
#define LOG_MAX (SOURCES * WRITES + 4000000u)

static gw_image *img;
static gw_fast F;
static xring *ring[SOURCES];
static atomic_bool sources_done[SOURCES];
static int slot_a, slot_b;

struct tx_log {
	uint64_t *t;
	size_t n;
	unsigned bad_frames;
};

static uint64_t now_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* low half c, high half ~c; bit 31 tells B000h (clear) from B001h (set) */
static uint64_t value_of(uint32_t c, bool b)
{
	uint32_t lo = (c & 0x7FFFFFFFu) | (b ? 0x80000000u : 0);
	return (uint64_t)lo | (uint64_t)(uint32_t)~lo << 32;
}

static bool frame_ok(const co_frame *f)
{
	uint64_t v = co_get_le(f->data, 8);
	uint32_t lo = (uint32_t)v, hi = (uint32_t)(v >> 32);
	bool tag = lo & 0x80000000u;

	if (f->len != 8 || hi != (uint32_t)~lo)
		return false;
	return (f->id == 0x181 && !tag) || (f->id == 0x182 && tag);
}

struct source_ctx {
	unsigned idx;
	struct tx_log log;
	uint64_t now; /* the time the frame is claimed with */
};

static int record(void *ctx, const co_frame *f)
{
	struct source_ctx *s = ctx;

	if (!frame_ok(f))
		s->log.bad_frames++;
	s->log.t[s->log.n++] = s->now;
	return 0;
}

static void *source_main(void *arg)
{
	struct source_ctx *s = arg;

	for (uint32_t c = 0; c < WRITES; c++) {
		int slot = (c & 1) ? slot_b : slot_a;
		uint32_t held;
		uint16_t sent_nr[GW_FAST_SENT_MAX];

		gw_image_write(img, slot, value_of(c * SOURCES + s->idx, slot == slot_b));
		s->now = now_us();
		(void)gw_fast_try(&F, img, slot, s->now, record, s, &held, sent_nr);
		gw_fast_hold(&F, held);
		if (xring_push(ring[s->idx], &held, sizeof(held)) != 0)
			gw_fast_undo_hold(&F, held); /* dropped: never applied */
		/* every other write, let the owner catch up (as a line does
		 * between two frames), so that the gate is free often */
		for (unsigned spin = 0; (c & 1) && spin < 1000 && xring_count(ring[s->idx]); spin++)
			sched_yield();
	}
	atomic_store(&sources_done[s->idx], true);
	return NULL;
}

static gw_fast_desc desc_for(bool b)
{
	gw_fast_desc d = { .nr = 1, .can_id = b ? 0x182 : 0x181, .len = 8, .n = 1 };

	d.inhibit_us = INHIBIT_US;
	d.map[0] = (uint32_t)(b ? slot_b : slot_a) << 8 | 64;
	return d;
}

static void republish(bool b)
{
	gw_fast_desc d = desc_for(b);
	uint64_t until = 0;
	bool pending = false;

	gw_fast_publish(&F, &d, &until, &pending, 1, NULL);
}

static struct tx_log owner_log;

static void *owner_main(void *arg)
{
	unsigned rounds = 0;
	uint64_t t, next_event = 0, wait_until = 0;
	bool want = false;

	(void)arg;
	for (;;) {
		bool all_done = true;
		uint32_t held;

		for (unsigned i = 0; i < SOURCES; i++) {
			while (xring_pop(ring[i], &held, sizeof(held)) > 0)
				gw_fast_taken(&F, held, true);
			all_done &= atomic_load(&sources_done[i]);
		}
		if (all_done && xring_count(ring[0]) == 0 && xring_count(ring[1]) == 0)
			break;
		rounds++;
		/* the owner's own events, one about every 300 µs: an event the
		 * gate refuses waits until the time it names, as the core's */
		t = now_us();
		if (!want && t >= next_event)
			want = true;
		if (want && t >= wait_until) {
			uint64_t r = gw_fast_gate(&F, 1, CO_PDO_GATE_CLAIM, t);
			if (r == CO_PDO_GATE_GO) {
				owner_log.t[owner_log.n++] = t;
				want = false;
				next_event = t + 300;
			} else {
				wait_until = r;
			}
		}
		if (rounds % 997 == 0)
			republish((rounds / 997) & 1);
		if (rounds % 4099 == 0)
			gw_fast_gate(&F, 1, CO_PDO_GATE_RESET, now_us()); /* closes it */
		if (rounds % 4099 == 1)
			republish(false);
		if (owner_log.n + 10 >= LOG_MAX)
			break;
	}
	return NULL;
}

static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

static void test_two_senders_share_one_inhibit_time(void)
{
	pthread_t src[SOURCES], own;
	struct source_ctx ctx[SOURCES];
	uint64_t *all;
	size_t n = 0;
	unsigned bad = 0;

	TEST_ASSERT_EQUAL(0, gw_image_create(&img, 4));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB000, 0, 8, value_of(0, false)));
	TEST_ASSERT_EQUAL(0, gw_image_add(img, 0xB001, 0, 8, value_of(0, true)));
	gw_image_seal(img);
	slot_a = gw_image_find(img, 0xB000, 0);
	slot_b = gw_image_find(img, 0xB001, 0);
	TEST_ASSERT_EQUAL(0, gw_fast_init(&F, gw_image_count(img)));
	gw_fast_set_carrying(&F, true);
	republish(false);
	for (unsigned i = 0; i < SOURCES; i++) {
		TEST_ASSERT_EQUAL(0, xring_create(&ring[i], 256, sizeof(uint32_t), -1));
		ctx[i] = (struct source_ctx){ .idx = i };
		ctx[i].log.t = calloc(WRITES, sizeof(uint64_t));
		TEST_ASSERT_NOT_NULL(ctx[i].log.t);
	}
	owner_log.t = calloc(LOG_MAX, sizeof(uint64_t));
	TEST_ASSERT_NOT_NULL(owner_log.t);
	pthread_create(&own, NULL, owner_main, NULL);
	for (unsigned i = 0; i < SOURCES; i++)
		pthread_create(&src[i], NULL, source_main, &ctx[i]);
	for (unsigned i = 0; i < SOURCES; i++)
		pthread_join(src[i], NULL);
	pthread_join(own, NULL);

	all = calloc(LOG_MAX + SOURCES * WRITES, sizeof(uint64_t));
	TEST_ASSERT_NOT_NULL(all);
	for (unsigned i = 0; i < SOURCES; i++) {
		memcpy(all + n, ctx[i].log.t, ctx[i].log.n * sizeof(uint64_t));
		n += ctx[i].log.n;
		bad += ctx[i].log.bad_frames;
		TEST_ASSERT_TRUE_MESSAGE(ctx[i].log.n > 0, "a source never sent");
	}
	TEST_ASSERT_TRUE_MESSAGE(owner_log.n > 0, "the owner never sent");
	memcpy(all + n, owner_log.t, owner_log.n * sizeof(uint64_t));
	n += owner_log.n;
	qsort(all, n, sizeof(uint64_t), cmp_u64);
	for (size_t i = 1; i < n; i++)
		TEST_ASSERT_TRUE_MESSAGE(all[i] - all[i - 1] >= INHIBIT_US,
					 "two transmissions inside the inhibit time");
	TEST_ASSERT_EQUAL_MESSAGE(0, bad, "a frame mixed two publications");
	for (unsigned k = 0; k < GW_FAST_MAX; k++)
		TEST_ASSERT_EQUAL_HEX32(0, atomic_load(&F.t[k].busy) & ~GW_FAST_PENDING);
	{
		char msg[128];
		snprintf(msg, sizeof msg, "%zu transmissions checked: sources %zu + %zu, owner %zu",
			 n, ctx[0].log.n, ctx[1].log.n, owner_log.n);
		TEST_MESSAGE(msg);
	}

	free(all);
	free(owner_log.t);
	for (unsigned i = 0; i < SOURCES; i++) {
		free(ctx[i].log.t);
		xring_destroy(ring[i]);
	}
	gw_fast_fini(&F);
	gw_image_destroy(img);
}

void setUp(void) {}

void tearDown(void) {}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_two_senders_share_one_inhibit_time);
	return UNITY_END();
}
