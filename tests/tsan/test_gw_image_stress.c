/* SPDX-License-Identifier: MIT */
/*
 * Stress of the gateway's shared process image under ThreadSanitizer
 * (build/tsan): the real gateway/image.c and lines/xring.c, driven the way
 * gateway/gateway.c drives them, by one thread per "line".
 *
 * Every line owns four B-objects (1, 2, 4 and 8 bytes) that its RPDO would
 * write: it publishes each new value into the image (gw_image_write), then
 * sends it to every other line whose forwarding list holds the slot (one
 * ring message per update); a full ring is a counted drop plus a mark in
 * the target's gw_pdo_sync (gateway/pdo_sync.c, the real one), as in
 * image_written(). Every line also reads the objects its TPDOs map: the
 * messages it gets (each reported to gw_pdo_sync_received), the image values
 * gw_pdo_sync_take hands over, and the image directly at random moments. Each line rebuilds its own
 * forwarding list from its OD now and then while the others query it.
 *
 * The values are self-checking: an object of n >= 2 bytes holds a counter
 * in its low half and the complement of that counter in its high half, so
 * half of an old value with half of a new one is seen at once. Checked:
 * - no data race (TSan fails the run on one);
 * - no torn value, from the image or from a message;
 * - per reader and object, the image never goes back to an older value,
 *   and the messages of one ring come in the order written;
 * - the counters add up: for every writer, target and object, updates
 *   written = forwarded + dropped, forwarded = received by the target =
 *   the ring's pushed count, dropped = the ring's drop count; an object
 *   the target does not map is never sent; a target that lost updates of
 *   an object resynced it; at the end every line holds the last value of
 *   every object it maps. How often a resync overtook queued messages (the
 *   line's TPDO sends the newest value, then older ones) is reported.
 * One line does not drain its rings until each other line has seen a full
 * ring toward it, so drops and resyncs happen in every run.
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "unity.h"

#include "core/od.h"
#include "core/pdo.h"
#include "gateway/image.h"
#include "gateway/pdo_sync.h"
#include "lines/xring.h"

#define LINES 3u
#define OBJS 4u /* per line: 1, 2, 4 and 8 bytes */
#define SLOTS (LINES * OBJS)
#define ROUNDS 60000u     /* 4- and 8-byte objects: written every round */
#define SMALL_STRIDE 300u /* 1- and 2-byte objects: every 300th round, */
			  /* 200 writes, so their 8-bit counter never wraps */
#define RING_SLOTS 16u
#define REBUILD_EVERY 512u     /* rounds between two forwarding list rebuilds */
#define LATE_LINE (LINES - 1u) /* drains only once every writer saw it full */

static const uint8_t obj_size[OBJS] = { 1, 2, 4, 8 };

typedef struct fwd_msg {
	uint16_t slot;
	uint8_t from;
	uint64_t bits;
} fwd_msg;

typedef struct line_sim {
	unsigned id;
	co_od *od; /* its TPDOs: what the others forward to it */
	gw_fwd_list fwd;
	gw_pdo_sync lost;            /* updates lost on the way here */
	atomic_bool saw_full[LINES]; /* a push toward line j was refused */
	int own_slot[OBJS];
	/* written by this line's thread only, read by main after join */
	uint64_t writes[OBJS];
	uint64_t sent[LINES][OBJS], dropped[LINES][OBJS];
	uint64_t received[LINES][OBJS];
	uint64_t last_msg[SLOTS];   /* counter of the last message per slot */
	uint64_t last_image[SLOTS]; /* counter last read from the image */
	uint64_t applied[SLOTS];    /* this line's copy (its OD entry) */
	uint64_t resynced[SLOTS];
	uint64_t image_reads, regressions;
	unsigned torn, backwards, unmapped, misrouted;
} line_sim;

static gw_image *img;
static xring_mesh *mesh;
static line_sim sim[LINES];
static atomic_uint writers_left;

void setUp(void) {}

void tearDown(void) {}

static uint16_t obj_index(unsigned line, unsigned k)
{
	return (uint16_t)(0xB000u + line * 0x10u + k);
}

static uint64_t pattern(uint64_t count, uint8_t size)
{
	unsigned half = size * 4u; /* bits */

	if (size == 1)
		return count & 0xFFu;
	count &= (UINT64_C(1) << half) - 1;
	return count | (~count & ((UINT64_C(1) << half) - 1)) << half;
}

/* The counter behind a value, or -1 if the halves do not match (torn). */
static int64_t counter_of(uint64_t bits, uint8_t size)
{
	unsigned half = size * 4u;
	uint64_t mask;

	if (size == 1)
		return (int64_t)bits;
	mask = (UINT64_C(1) << half) - 1;
	if ((~bits >> half & mask) != (bits & mask))
		return -1;
	return (int64_t)(bits & mask);
}

static unsigned owner_of(int slot)
{
	const gw_image_slot *s = gw_image_slot_at(img, slot);

	return (s->index - 0xB000u) / 0x10u;
}

static bool maps(const line_sim *me, int slot)
{
	return gw_fwd_list_has(&me->fwd, slot);
}

/* The counter of a value of slot read from the image, as a TPDO would
 * read it; -1 if torn. */
static int64_t image_value_seen(line_sim *me, int slot, uint64_t bits)
{
	int64_t c = counter_of(bits, gw_image_slot_at(img, slot)->size);

	me->image_reads++;
	if (c < 0) {
		me->torn++;
		return -1;
	}
	if ((uint64_t)c < me->last_image[slot])
		me->backwards++;
	me->last_image[slot] = (uint64_t)c;
	return c;
}

/* gw_pdo_sync_apply_fn: as pdo_apply() on a resync, stored only if it
 * differs from this line's copy. */
static bool resync_apply(void *ctx, int slot, uint64_t bits)
{
	line_sim *me = ctx;
	int64_t c;

	me->resynced[slot]++;
	c = image_value_seen(me, slot, bits);
	if (c < 0 || (uint64_t)c == me->applied[slot])
		return false;
	me->applied[slot] = (uint64_t)c;
	return true;
}

static void publish(line_sim *me, unsigned k)
{
	int slot = me->own_slot[k];
	fwd_msg m = { .slot = (uint16_t)slot, .from = (uint8_t)me->id };

	m.bits = pattern(++me->writes[k], obj_size[k]);
	gw_image_write(img, slot, m.bits);
	for (unsigned j = 0; j < LINES; j++) {
		if (j == me->id || !maps(&sim[j], slot))
			continue;
		if (xring_push(xring_mesh_get(mesh, me->id, j), &m, sizeof m) == 0) {
			me->sent[j][k]++;
			continue;
		}
		me->dropped[j][k]++;
		atomic_store(&me->saw_full[j], true);
		gw_pdo_sync_mark(&sim[j].lost, slot);
	}
}

/* Pop every inbound ring until all are empty, then apply the resyncs. */
static void drain(line_sim *me)
{
	bool any;

	do {
		any = false;
		for (unsigned from = 0; from < LINES; from++) {
			xring *r = xring_mesh_get(mesh, from, me->id);
			fwd_msg m;
			int64_t c;
			if (!r)
				continue;
			while (xring_pop(r, &m, sizeof m) > 0) {
				unsigned k;
				any = true;
				if (m.from != from || m.slot >= SLOTS || owner_of(m.slot) != from) {
					me->misrouted++;
					continue;
				}
				if (!maps(me, m.slot))
					me->unmapped++;
				k = gw_image_slot_at(img, m.slot)->index - obj_index(from, 0);
				c = counter_of(m.bits, obj_size[k]);
				if (c < 0) {
					me->torn++;
					continue;
				}
				if ((uint64_t)c <= me->last_msg[m.slot])
					me->backwards++;
				me->last_msg[m.slot] = (uint64_t)c;
				/* Not an error: a resync may have applied a newer
				 * value than a message queued before it. Then
				 * gw_pdo_sync_received brings the newest again. */
				if ((uint64_t)c < me->applied[m.slot])
					me->regressions++;
				me->applied[m.slot] = (uint64_t)c;
				me->received[from][k]++;
				gw_pdo_sync_received(&me->lost, img, m.slot, m.bits);
			}
		}
	} while (any);
	gw_pdo_sync_take(&me->lost, img, resync_apply, me);
}

static bool late_line_may_drain(void)
{
	for (unsigned i = 0; i < LINES; i++)
		if (i != LATE_LINE && !atomic_load(&sim[i].saw_full[LATE_LINE]))
			return false;
	return true;
}

static void *line_main(void *arg)
{
	line_sim *me = arg;
	unsigned peek = me->id;

	for (unsigned round = 1; round <= ROUNDS; round++) {
		for (unsigned k = 0; k < OBJS; k++)
			if (obj_size[k] > 2 || round % SMALL_STRIDE == 0)
				publish(me, k);
		/* a TPDO of this line sampling a mapped object of another line */
		peek = (peek + 1) % SLOTS;
		if (owner_of((int)peek) != me->id && maps(me, (int)peek))
			image_value_seen(me, (int)peek, gw_image_read(img, (int)peek));
		if (round % REBUILD_EVERY == 0)
			gw_fwd_list_rebuild(&me->fwd, img, me->od);
		if (me->id != LATE_LINE || late_line_may_drain())
			drain(me);
	}
	atomic_fetch_sub(&writers_left, 1);
	while (atomic_load(&writers_left) > 0)
		drain(me);
	/* every writer is done: what is still queued or flagged comes now */
	drain(me);
	return NULL;
}

/* Line j maps every object of the other lines, each in a TPDO of its own,
 * except the 2-byte object of line j+1: that one sits in an invalid TPDO,
 * so it is not in j's forwarding list and must never be sent to j. */
static bool line_maps(unsigned j, unsigned owner, unsigned k)
{
	return owner != j && !(owner == (j + 1) % LINES && obj_size[k] == 2);
}

static void build_od(line_sim *me)
{
	uint16_t nr = 1;

	TEST_ASSERT_EQUAL(0, co_od_create(&me->od, 64));
	for (unsigned owner = 0; owner < LINES; owner++) {
		for (unsigned k = 0; k < OBJS; k++) {
			uint32_t map = CO_PDO_MAP(obj_index(owner, k), 0, obj_size[k] * 8u);
			bool valid = line_maps(me->id, owner, k);
			co_pdo_desc d = { .dir = CO_PDO_TX,
					  .nr = nr,
					  .cob_id = (valid ? 0 : CO_PDO_COB_INVALID) |
						    (0x180u + nr),
					  .tt = 255,
					  .n_map = 1,
					  .map = &map };
			if (owner == me->id)
				continue;
			TEST_ASSERT_EQUAL(0, co_od_add_pdo(me->od, &d));
			nr++;
		}
	}
	TEST_ASSERT_EQUAL(0, gw_fwd_list_init(&me->fwd, img));
	TEST_ASSERT_EQUAL((LINES - 1) * OBJS - 1, gw_fwd_list_rebuild(&me->fwd, img, me->od));
}

static void check_line(const line_sim *to)
{
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, to->torn, "torn value");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, to->backwards, "a value went back");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, to->unmapped, "an unmapped object was forwarded");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, to->misrouted, "a message from the wrong line");
	for (unsigned from = 0; from < LINES; from++) {
		const line_sim *w = &sim[from];
		xring *r = xring_mesh_get(mesh, from, to->id);
		uint64_t sent = 0, dropped = 0;
		xring_stats st;

		if (!r)
			continue;
		for (unsigned k = 0; k < OBJS; k++) {
			int slot = w->own_slot[k];
			if (!line_maps(to->id, from, k)) {
				TEST_ASSERT_EQUAL_UINT64(0, w->sent[to->id][k] +
								    w->dropped[to->id][k]);
				continue;
			}
			/* every update either delivered or counted as dropped */
			TEST_ASSERT_EQUAL_UINT64(w->writes[k],
						 w->sent[to->id][k] + w->dropped[to->id][k]);
			TEST_ASSERT_EQUAL_UINT64(w->sent[to->id][k], to->received[from][k]);
			if (w->dropped[to->id][k])
				TEST_ASSERT_TRUE(to->resynced[slot] > 0);
			/* and the line ends with the last value written, even
			 * when a resync took it before older messages still
			 * queued were applied */
			TEST_ASSERT_EQUAL_UINT64(w->writes[k], to->applied[slot]);
			sent += w->sent[to->id][k];
			dropped += w->dropped[to->id][k];
		}
		xring_stats_get(r, &st);
		TEST_ASSERT_EQUAL_UINT64(sent, st.pushed);
		TEST_ASSERT_EQUAL_UINT64(dropped, st.dropped);
		if (to->id == LATE_LINE)
			TEST_ASSERT_TRUE(dropped > 0);
	}
}

static void test_lines_share_the_image_without_torn_values(void)
{
	pthread_t th[LINES];
	uint64_t writes = 0, sent = 0, dropped = 0, reads = 0, regressions = 0;

	TEST_ASSERT_EQUAL(0, gw_image_create(&img, SLOTS));
	for (unsigned line = 0; line < LINES; line++)
		for (unsigned k = 0; k < OBJS; k++)
			TEST_ASSERT_EQUAL(0, gw_image_add(img, obj_index(line, k), 0, obj_size[k],
							  pattern(0, obj_size[k])));
	gw_image_seal(img);
	TEST_ASSERT_EQUAL(0, xring_mesh_create(&mesh, LINES, NULL, RING_SLOTS, sizeof(fwd_msg)));
	memset(sim, 0, sizeof sim);
	for (unsigned i = 0; i < LINES; i++) {
		sim[i].id = i;
		for (unsigned k = 0; k < OBJS; k++)
			sim[i].own_slot[k] = gw_image_find(img, obj_index(i, k), 0);
		TEST_ASSERT_EQUAL(0, gw_pdo_sync_init(&sim[i].lost, SLOTS));
		build_od(&sim[i]);
	}
	atomic_store(&writers_left, LINES);
	for (unsigned i = 0; i < LINES; i++)
		TEST_ASSERT_EQUAL(0, pthread_create(&th[i], NULL, line_main, &sim[i]));
	for (unsigned i = 0; i < LINES; i++)
		pthread_join(th[i], NULL);

	for (unsigned i = 0; i < LINES; i++) {
		check_line(&sim[i]);
		for (unsigned k = 0; k < OBJS; k++) {
			const gw_image_slot *s = gw_image_slot_at(img, sim[i].own_slot[k]);
			TEST_ASSERT_EQUAL_UINT64(sim[i].writes[k], atomic_load(&s->writes));
			TEST_ASSERT_EQUAL_UINT64(pattern(sim[i].writes[k], obj_size[k]),
						 gw_image_read(img, sim[i].own_slot[k]));
			writes += sim[i].writes[k];
			for (unsigned j = 0; j < LINES; j++) {
				sent += sim[i].sent[j][k];
				dropped += sim[i].dropped[j][k];
			}
		}
		reads += sim[i].image_reads;
		regressions += sim[i].regressions;
	}
	char line[200];
	snprintf(line, sizeof line,
		 "%llu updates published, %llu forwarded, %llu dropped and resynced, "
		 "%llu image reads, %llu values overtaken by a resync",
		 (unsigned long long)writes, (unsigned long long)sent, (unsigned long long)dropped,
		 (unsigned long long)reads, (unsigned long long)regressions);
	TEST_MESSAGE(line);
	for (unsigned i = 0; i < LINES; i++) {
		gw_fwd_list_fini(&sim[i].fwd);
		gw_pdo_sync_fini(&sim[i].lost);
		co_od_destroy(sim[i].od);
	}
	xring_mesh_destroy(mesh);
	gw_image_destroy(img);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_lines_share_the_image_without_torn_values);
	return UNITY_END();
}
