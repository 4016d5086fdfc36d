/* SPDX-License-Identifier: MIT */
/*
 * The device object layer's core parts (devobj/value.h, devobj/mirror.h):
 *   - values out of and into PDO frames by CiA 301 type: every integer
 *     width sign- or zero-extended, reals, BOOLEAN, strings, unknown types;
 *     the checks a write gets (length, range of the mapped bits);
 *   - the mirror on two cores on the in-memory bus: the daemon (id 1)
 *     programs its free RPDOs/TPDOs after a slave's (id 5) layout, the
 *     slave's TPDO frames arrive on them byte for byte, a frame the daemon
 *     produces sets the slave's objects; hand-written PDOs are left alone
 *     and their COB-IDs refused; a layout larger than the free records is
 *     reported per PDO; invalidation releases the records.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/frame.h"
#include "core/nmt.h"
#include "core/od.h"
#include "core/pdo.h"
#include "core/pdo_layout.h"
#include "core/sdo.h"
#include "core/sync.h"
#include "devobj/mirror.h"
#include "devobj/value.h"
#include "tests/unit/support/test_bus.h"

#define DAEMON 1
#define SLAVE 5

/* ---- values ------------------------------------------------------------------- */

static co_pdo_layout_entry entry(uint8_t offset, uint8_t bits, uint16_t type)
{
	return (co_pdo_layout_entry){
		.index = 0x2000, .sub = 1, .bits = bits, .offset = offset, .type = type
	};
}

static void expect_extract(const char *frame_hex, co_pdo_layout_entry e, uint16_t asked,
			   uint16_t want_type, const char *want_hex)
{
	co_frame f = tb_frame(0x181, frame_hex);
	uint8_t out[8] = { 0 };
	uint16_t type = devobj_value_type(&e, asked);
	TEST_ASSERT_EQUAL_HEX16(want_type, type);
	uint8_t len = devobj_value_extract(f.data, &e, type, out);
	co_frame want = tb_frame(0, want_hex);
	TEST_ASSERT_EQUAL_UINT8(want.len, len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(want.data, out, len);
}

void test_value_integers_by_width(void)
{
	/* INTEGER8..64: sign-extended from the mapped length */
	expect_extract("FE", entry(0, 8, CO_T_INTEGER8), 0, CO_T_INTEGER8, "FE");
	expect_extract("00 FE FF", entry(8, 16, CO_T_INTEGER16), 0, CO_T_INTEGER16, "FE FF");
	expect_extract("FD FF FF", entry(0, 24, CO_T_INTEGER24), 0, CO_T_INTEGER24, "FD FF FF");
	expect_extract("01 02 03 84", entry(0, 32, CO_T_INTEGER32), 0, CO_T_INTEGER32,
		       "01 02 03 84");
	expect_extract("01 02 03 04 85", entry(0, 40, CO_T_INTEGER40), 0, CO_T_INTEGER40,
		       "01 02 03 04 85");
	expect_extract("01 02 03 04 05 86", entry(0, 48, CO_T_INTEGER48), 0, CO_T_INTEGER48,
		       "01 02 03 04 05 86");
	expect_extract("01 02 03 04 05 06 87", entry(0, 56, CO_T_INTEGER56), 0, CO_T_INTEGER56,
		       "01 02 03 04 05 06 87");
	expect_extract("01 02 03 04 05 06 07 88", entry(0, 64, CO_T_INTEGER64), 0, CO_T_INTEGER64,
		       "01 02 03 04 05 06 07 88");
	/* an INTEGER32 mapped with 12 bits: bit 11 is the sign */
	expect_extract("00 08", entry(0, 12, CO_T_INTEGER32), 0, CO_T_INTEGER32, "00 F8 FF FF");
	/* UNSIGNEDn zero-extended */
	expect_extract("FF 0F", entry(4, 8, CO_T_UNSIGNED32), 0, CO_T_UNSIGNED32, "FF 00 00 00");
	expect_extract("01 02 83", entry(0, 24, CO_T_UNSIGNED24), 0, CO_T_UNSIGNED24, "01 02 83");
	expect_extract("01 02 03 04 05 06 87", entry(0, 56, CO_T_UNSIGNED56), 0, CO_T_UNSIGNED56,
		       "01 02 03 04 05 06 87");
}

void test_value_reals_booleans_strings(void)
{
	/* REAL32 1.5 = 3FC00000h, REAL64 -2.25 = C002000000000000h */
	expect_extract("AA 00 00 C0 3F", entry(8, 32, CO_T_REAL32), 0, CO_T_REAL32, "00 00 C0 3F");
	expect_extract("00 00 00 00 00 00 02 C0", entry(0, 64, CO_T_REAL64), 0, CO_T_REAL64,
		       "00 00 00 00 00 00 02 C0");
	/* a BOOLEAN mapped with 1 bit (bit 3 of the first byte), with 8 */
	expect_extract("08", entry(3, 1, CO_T_BOOLEAN), 0, CO_T_BOOLEAN, "01");
	expect_extract("F7", entry(3, 1, CO_T_BOOLEAN), 0, CO_T_BOOLEAN, "00");
	/* VISIBLE_STRING and OCTET_STRING: the mapped bytes */
	expect_extract("00 41 42 43", entry(8, 24, CO_T_VISIBLE_STRING), 0, CO_T_VISIBLE_STRING,
		       "41 42 43");
	expect_extract("DE AD BE EF", entry(0, 32, CO_T_OCTET_STRING), 0, CO_T_OCTET_STRING,
		       "DE AD BE EF");
	expect_extract("DE AD", entry(0, 16, CO_T_DOMAIN), 0, CO_T_DOMAIN, "DE AD");
}

void test_value_unknown_and_asked_types(void)
{
	/* nobody gave a type: UNSIGNEDn of the mapped length in bytes */
	expect_extract("FF FF", entry(0, 12, 0), 0, CO_T_UNSIGNED16, "FF 0F");
	expect_extract("01 02 03", entry(0, 24, 0), 0, CO_T_UNSIGNED24, "01 02 03");
	expect_extract("80", entry(0, 8, 0), 0, CO_T_UNSIGNED8, "80");
	/* a client may read an untyped entry as a signed type of its size */
	expect_extract("80", entry(0, 8, 0), CO_T_INTEGER8, CO_T_INTEGER8, "80");
	/* a type narrower than the mapping, or a string of odd bits: none */
	co_pdo_layout_entry e = entry(0, 16, 0);
	TEST_ASSERT_EQUAL(0, devobj_value_type(&e, CO_T_UNSIGNED8));
	e = entry(0, 12, 0);
	TEST_ASSERT_EQUAL(0, devobj_value_type(&e, CO_T_VISIBLE_STRING));
	TEST_ASSERT_EQUAL(0, devobj_value_type(&e, 0x0E)); /* no basic type */
}

void test_value_insert_checks(void)
{
	uint8_t frame[8] = { 0 };
	co_pdo_layout_entry e = entry(4, 8, CO_T_INTEGER16);
	const uint8_t minus2[2] = { 0xFE, 0xFF }, big[2] = { 0x00, 0x01 };
	/* -2 fits 8 bits: stored at bit 4 */
	TEST_ASSERT_EQUAL_HEX32(0, devobj_value_insert(frame, &e, CO_T_INTEGER16, minus2, 2));
	TEST_ASSERT_EQUAL_HEX8(0xE0, frame[0]);
	TEST_ASSERT_EQUAL_HEX8(0x0F, frame[1]);
	/* 256 does not */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE,
				devobj_value_insert(frame, &e, CO_T_INTEGER16, big, 2));
	/* wrong lengths, as an SDO server answers them */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_LOW,
				devobj_value_insert(frame, &e, CO_T_INTEGER16, big, 1));
	const uint8_t three[3] = { 1, 2, 3 };
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_HIGH,
				devobj_value_insert(frame, &e, CO_T_INTEGER16, three, 3));
	/* BOOLEAN: 0 or 1 only */
	co_pdo_layout_entry b = entry(0, 1, CO_T_BOOLEAN);
	const uint8_t two = 2, one = 1;
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE,
				devobj_value_insert(frame, &b, CO_T_BOOLEAN, &two, 1));
	TEST_ASSERT_EQUAL_HEX32(0, devobj_value_insert(frame, &b, CO_T_BOOLEAN, &one, 1));
	TEST_ASSERT_EQUAL_HEX8(0xE1, frame[0]);
	/* a string shorter than mapped is padded with zeros; longer refused */
	uint8_t sf[8] = { 0xFF, 0xFF, 0xFF, 0xFF };
	co_pdo_layout_entry s = entry(0, 32, CO_T_VISIBLE_STRING);
	TEST_ASSERT_EQUAL_HEX32(
		0, devobj_value_insert(sf, &s, CO_T_VISIBLE_STRING, (const uint8_t *)"ab", 2));
	TEST_ASSERT_EQUAL_HEX8_ARRAY("ab\0\0", sf, 4);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_LEN_HIGH, devobj_value_insert(sf, &s, CO_T_VISIBLE_STRING,
								     (const uint8_t *)"abcde", 5));
}

/* ---- the mirror on two cores ----------------------------------------------------- */

static tb_bus bus;
static tb_port *dp, *sp;
static co_pdo_layout *layout;
static devobj_mirror mirror;

/* The slave: objects of several types in three TPDOs and one RPDO. */
static co_od *slave_od(void)
{
	co_od *o;
	const uint32_t t1[] = { CO_PDO_MAP(0x2000, 0, 16), CO_PDO_MAP(0x2001, 0, 8),
				CO_PDO_MAP(0x2002, 0, 1) };
	const uint32_t t2[] = { CO_PDO_MAP(0x2003, 0, 32) };
	const uint32_t t3[] = { CO_PDO_MAP(0x2004, 0, 24) };
	const uint32_t r1[] = { CO_PDO_MAP(0x2100, 0, 16), CO_PDO_MAP(0x2101, 0, 8) };
	co_pdo_desc pdos[] = {
		{ .dir = CO_PDO_TX, .nr = 1, .cob_id = 0x185, .tt = 254, .n_map = 3, .map = t1 },
		{ .dir = CO_PDO_TX, .nr = 2, .cob_id = 0x285, .tt = 254, .n_map = 1, .map = t2 },
		{ .dir = CO_PDO_TX, .nr = 3, .cob_id = 0x385, .tt = 254, .n_map = 1, .map = t3 },
		{ .dir = CO_PDO_RX, .nr = 1, .cob_id = 0x205, .tt = 254, .n_map = 2, .map = r1 },
	};
	TEST_ASSERT_EQUAL(0, co_od_create(&o, 64));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x2000, 0, CO_T_INTEGER16, CO_ACC_RWR, 0xFF85, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x2001, 0, CO_T_UNSIGNED8, CO_ACC_RWR, 0x42, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x2002, 0, CO_T_BOOLEAN, CO_ACC_RWR, 1, NULL));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(o, 0x2003, 0, CO_T_REAL32, CO_ACC_RWR, 0x3FC00000, NULL));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(o, 0x2004, 0, CO_T_INTEGER24, CO_ACC_RWR, 0xFFFFFE, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x2100, 0, CO_T_UNSIGNED16, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x2101, 0, CO_T_INTEGER8, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_sync(o, 0, 0, 0));
	for (unsigned i = 0; i < sizeof pdos / sizeof pdos[0]; i++)
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &pdos[i]));
	return o;
}

/* The daemon: RPDO 1 written by hand (consumes another node's 181h),
 * RPDOs 2..n_rx and TPDOs 1..n_tx left alone. */
static co_od *daemon_od(uint16_t n_rx, uint16_t n_tx)
{
	co_od *o;
	const uint32_t m[] = { CO_PDO_MAP(0x3000, 0, 8) };
	TEST_ASSERT_EQUAL(0, co_od_create(&o, 64));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x3000, 0, CO_T_UNSIGNED8, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_sync(o, 0, 0, 0));
	co_pdo_desc hand = {
		.dir = CO_PDO_RX, .nr = 1, .cob_id = 0x181, .tt = 254, .n_map = 1, .map = m
	};
	TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &hand));
	for (uint16_t n = 2; n <= n_rx; n++) {
		co_pdo_desc d = {
			.dir = CO_PDO_RX, .nr = n, .cob_id = CO_PDO_COB_INVALID, .tt = 255
		};
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &d));
	}
	for (uint16_t n = 1; n <= n_tx; n++) {
		co_pdo_desc d = {
			.dir = CO_PDO_TX, .nr = n, .cob_id = CO_PDO_COB_INVALID, .tt = 255
		};
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &d));
	}
	return o;
}

/* The slave's layout as a file would give it (types known). */
static void learn_slave_layout(void)
{
	co_pdo_layout_pdo t1 = { .nr = 1, .cob = 0x185, .tt = 254, .n = 3 };
	t1.map[0] = (co_pdo_layout_entry){ .index = 0x2000, .bits = 16, .type = CO_T_INTEGER16 };
	t1.map[1] = (co_pdo_layout_entry){ .index = 0x2001, .bits = 8, .type = CO_T_UNSIGNED8 };
	t1.map[2] = (co_pdo_layout_entry){ .index = 0x2002, .bits = 1, .type = CO_T_BOOLEAN };
	co_pdo_layout_pdo t2 = { .nr = 2, .cob = 0x285, .tt = 254, .n = 1 };
	t2.map[0] = (co_pdo_layout_entry){ .index = 0x2003, .bits = 32, .type = CO_T_REAL32 };
	co_pdo_layout_pdo t3 = { .nr = 3, .cob = 0x385, .tt = 254, .n = 1 };
	t3.map[0] = (co_pdo_layout_entry){ .index = 0x2004, .bits = 24, .type = CO_T_INTEGER24 };
	co_pdo_layout_pdo r1 = { .nr = 1, .cob = 0x205, .tt = 254, .n = 2 };
	r1.map[0] = (co_pdo_layout_entry){ .index = 0x2100, .bits = 16, .type = CO_T_UNSIGNED16 };
	r1.map[1] = (co_pdo_layout_entry){ .index = 0x2101, .bits = 8, .type = CO_T_INTEGER8 };
	TEST_ASSERT_EQUAL(0, co_pdo_layout_begin(layout, SLAVE, CO_PDO_LAYOUT_FILE));
	TEST_ASSERT_NOT_NULL(co_pdo_layout_add(layout, SLAVE, CO_PDO_TX, &t1));
	TEST_ASSERT_NOT_NULL(co_pdo_layout_add(layout, SLAVE, CO_PDO_TX, &t2));
	TEST_ASSERT_NOT_NULL(co_pdo_layout_add(layout, SLAVE, CO_PDO_TX, &t3));
	TEST_ASSERT_NOT_NULL(co_pdo_layout_add(layout, SLAVE, CO_PDO_RX, &r1));
	co_pdo_layout_commit(layout, SLAVE, 0);
}

static void start(uint16_t n_rx, uint16_t n_tx)
{
	co_node_config dc = { .node_id = DAEMON };
	co_node_config sc = { .node_id = SLAVE };
	const uint32_t nodes[4] = { 1u << SLAVE, 0, 0, 0 };

	tb_init(&bus);
	dp = tb_add_node(&bus, &dc, daemon_od(n_rx, n_tx));
	sp = tb_add_node(&bus, &sc, slave_od());
	TEST_ASSERT_NOT_NULL(dp);
	TEST_ASSERT_NOT_NULL(sp);
	TEST_ASSERT_EQUAL(0, co_pdo_layout_create(&layout, nodes, 8));
	TEST_ASSERT_EQUAL(0, devobj_mirror_create(&mirror, dp->node, layout, nodes, NULL));
	tb_advance(&bus, 0);
	co_nmt_local_cmd(dp->node, CO_NMT_CS_START, 0);
	co_nmt_local_cmd(sp->node, CO_NMT_CS_START, 0);
	tb_advance(&bus, 1000);
}

void setUp(void)
{
	layout = NULL;
	memset(&mirror, 0, sizeof mirror);
}

void tearDown(void)
{
	devobj_mirror_destroy(&mirror);
	co_pdo_layout_destroy(layout);
	tb_fini(&bus);
}

/* The last RPDO event of the daemon for its RPDO nr. */
static const co_event *last_rpdo(uint16_t nr)
{
	for (size_t i = dp->n_ev; i-- > 0;)
		if (dp->ev[i].kind == CO_EV_RPDO && dp->ev[i].u.pdo.nr == nr)
			return &dp->ev[i];
	return NULL;
}

void test_mirror_consumes_every_tpdo_and_produces_the_rpdo(void)
{
	start(4, 2);
	/* free at start-up: RPDO 2..4, TPDO 1..2; RPDO 1 is the configuration's */
	TEST_ASSERT_EQUAL(3, mirror.n_rec[CO_PDO_RX]);
	TEST_ASSERT_EQUAL(2, mirror.n_rec[CO_PDO_TX]);
	TEST_ASSERT_TRUE(co_od_has_index(dp->od, DEVOBJ_SLOT_RX_INDEX));
	TEST_ASSERT_FALSE(devobj_mirror_sync(&mirror, SLAVE)); /* nothing learnt yet */

	learn_slave_layout();
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	TEST_ASSERT_EQUAL(DEVOBJ_M_FULL, mirror.node[SLAVE].status);
	TEST_ASSERT_FALSE(devobj_mirror_sync(&mirror, SLAVE)); /* same generation */

	/* RPDO 2 consumes 185h with the slot's 5A00h:1 over 4 bytes, made
	 * through the OD as an SDO client would make it */
	uint32_t cob = 0, map = 0;
	uint8_t tt = 0;
	TEST_ASSERT_EQUAL(0, co_od_get_u32(dp->od, 0x1401, 1, &cob));
	TEST_ASSERT_EQUAL(0, co_od_get_u32(dp->od, 0x1601, 1, &map));
	TEST_ASSERT_EQUAL(0, co_od_get_u8(dp->od, 0x1401, 2, &tt));
	TEST_ASSERT_EQUAL_HEX32(0x185, cob);
	TEST_ASSERT_EQUAL_HEX32(CO_PDO_MAP(DEVOBJ_SLOT_RX_INDEX, 1, 32), map);
	TEST_ASSERT_EQUAL(255, tt);
	TEST_ASSERT_TRUE(co_pdo_is_valid(dp->node, CO_PDO_RX, 2));
	TEST_ASSERT_TRUE(co_pdo_is_valid(dp->node, CO_PDO_RX, 4));
	TEST_ASSERT_TRUE(co_pdo_is_valid(dp->node, CO_PDO_TX, 1));
	TEST_ASSERT_FALSE(co_pdo_is_valid(dp->node, CO_PDO_TX, 2));

	/* the slave sends TPDO 1: the daemon's RPDO 2 gets it byte for byte,
	 * and the value of 2000h (INTEGER16 -123) comes out of it */
	tb_events_clear(dp);
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_event(sp->node, 1, bus.now));
	tb_advance(&bus, 100);
	const co_event *ev = last_rpdo(2);
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL(4, ev->u.pdo.len);
	const uint8_t want[4] = { 0x85, 0xFF, 0x42, 0x01 };
	TEST_ASSERT_EQUAL_HEX8_ARRAY(want, ev->u.pdo.data, 4);
	const devobj_record *r = devobj_mirror_record_of(&mirror, CO_PDO_RX, 2);
	TEST_ASSERT_NOT_NULL(r);
	const co_pdo_layout_node *ln = co_pdo_layout_node_get(layout, SLAVE);
	const co_pdo_layout_entry *e = &ln->pdo[CO_PDO_TX][r->dev_pos].map[0];
	uint8_t v[8];
	TEST_ASSERT_EQUAL(2, devobj_value_extract(ev->u.pdo.data, e, CO_T_INTEGER16, v));
	TEST_ASSERT_EQUAL_HEX8(0x85, v[0]);
	TEST_ASSERT_EQUAL_HEX8(0xFF, v[1]);

	/* the daemon produces the slave's RPDO 1 from its TPDO 1 */
	const devobj_record *t = devobj_mirror_record_of(&mirror, CO_PDO_TX, 1);
	TEST_ASSERT_NOT_NULL(t);
	co_od_entry *slot = co_od_find(dp->od, DEVOBJ_SLOT_TX_INDEX, t->slot_sub);
	TEST_ASSERT_NOT_NULL(slot);
	co_od_entry_set_raw(slot, 0xF9BEEFu); /* 2100h = BEEFh, 2101h = -7 */
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_event(dp->node, t->nr, bus.now));
	tb_advance(&bus, 100);
	TEST_ASSERT_TRUE(tb_frame_is(tb_last_from_id(&bus, dp->idx, 0x205), 0x205, "EF BE F9"));
	uint16_t u16 = 0;
	int8_t i8 = 0;
	TEST_ASSERT_EQUAL(0, co_od_get_u16(sp->od, 0x2100, 0, &u16));
	TEST_ASSERT_EQUAL(0, co_od_get_i8(sp->od, 0x2101, 0, &i8));
	TEST_ASSERT_EQUAL_HEX16(0xBEEF, u16);
	TEST_ASSERT_EQUAL(-7, i8);

	/* a deadline of the slave's RPDO is kept: the TPDO repeats by itself */
	TEST_ASSERT_EQUAL_HEX32(0, devobj_mirror_keep_sending(&mirror, t, 50));
	uint16_t ev_ms = 0;
	TEST_ASSERT_EQUAL(0, co_od_get_u16(dp->od, (uint16_t)(0x1800 + t->nr - 1), 5, &ev_ms));
	TEST_ASSERT_EQUAL(50, ev_ms);
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_event(dp->node, t->nr, bus.now));
	size_t before = tb_count_from_id(&bus, dp->idx, 0x205, 0);
	tb_advance(&bus, 210000);
	TEST_ASSERT_TRUE(tb_count_from_id(&bus, dp->idx, 0x205, 0) >= before + 4);
}

void test_mirror_reports_what_does_not_fit(void)
{
	/* two free RPDOs for three TPDOs of the slave */
	start(3, 1);
	learn_slave_layout();
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	const devobj_node_mirror *nm = &mirror.node[SLAVE];
	TEST_ASSERT_EQUAL(DEVOBJ_M_PARTIAL, nm->status);
	TEST_ASSERT_EQUAL(1, nm->missing);
	TEST_ASSERT_EQUAL(DEVOBJ_R_NO_RECORD, nm->reason);
	TEST_ASSERT_EQUAL(DEVOBJ_R_NONE, nm->why[CO_PDO_TX][0]);
	TEST_ASSERT_EQUAL(DEVOBJ_R_NONE, nm->why[CO_PDO_TX][1]);
	TEST_ASSERT_EQUAL(DEVOBJ_R_NO_RECORD, nm->why[CO_PDO_TX][2]);
	TEST_ASSERT_EQUAL(-1, devobj_mirror_record_for(&mirror, SLAVE, CO_PDO_TX, 2));
	TEST_ASSERT_EQUAL_STRING("no-free-pdo", devobj_reason_to_string(nm->reason));
}

void test_mirror_leaves_hand_written_cob_ids_alone(void)
{
	start(4, 1);
	/* the configuration's RPDO 1 consumes 181h; a slave TPDO on 181h must
	 * not get a second consumer */
	co_pdo_layout_pdo t = { .nr = 1, .cob = 0x181, .tt = 254, .n = 1 };
	t.map[0] = (co_pdo_layout_entry){ .index = 0x2001, .bits = 8, .type = CO_T_UNSIGNED8 };
	TEST_ASSERT_EQUAL(0, co_pdo_layout_begin(layout, SLAVE, CO_PDO_LAYOUT_SCAN));
	TEST_ASSERT_NOT_NULL(co_pdo_layout_add(layout, SLAVE, CO_PDO_TX, &t));
	co_pdo_layout_commit(layout, SLAVE, 0);
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	TEST_ASSERT_EQUAL(DEVOBJ_M_NONE, mirror.node[SLAVE].status);
	TEST_ASSERT_EQUAL(DEVOBJ_R_COB_IN_USE, mirror.node[SLAVE].reason);
	/* the hand-written RPDO is as it was */
	uint32_t cob = 0;
	TEST_ASSERT_EQUAL(0, co_od_get_u32(dp->od, 0x1400, 1, &cob));
	TEST_ASSERT_EQUAL_HEX32(0x181, cob);
	TEST_ASSERT_FALSE(co_pdo_is_valid(dp->node, CO_PDO_RX, 2));
}

void test_mirror_released_on_invalidation_and_after_a_reset(void)
{
	start(4, 1);
	learn_slave_layout();
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	TEST_ASSERT_TRUE(co_pdo_is_valid(dp->node, CO_PDO_RX, 2));

	/* the slave booted again: its layout is invalid, the records free */
	co_pdo_layout_invalidate(layout, SLAVE);
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	TEST_ASSERT_EQUAL(DEVOBJ_M_WAITING, mirror.node[SLAVE].status);
	for (uint16_t nr = 2; nr <= 4; nr++)
		TEST_ASSERT_FALSE(co_pdo_is_valid(dp->node, CO_PDO_RX, nr));
	TEST_ASSERT_FALSE(co_pdo_is_valid(dp->node, CO_PDO_TX, 1));
	uint32_t cob = 0;
	uint8_t n = 1;
	TEST_ASSERT_EQUAL(0, co_od_get_u32(dp->od, 0x1401, 1, &cob));
	TEST_ASSERT_EQUAL(0, co_od_get_u8(dp->od, 0x1601, 0, &n));
	TEST_ASSERT_EQUAL_HEX32(CO_PDO_COB_INVALID, cob);
	TEST_ASSERT_EQUAL(0, n);
	TEST_ASSERT_NULL(devobj_mirror_record_of(&mirror, CO_PDO_RX, 2));

	/* learnt again, then our own reset communication: programmed anew */
	learn_slave_layout();
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	co_nmt_local_cmd(dp->node, CO_NMT_CS_RESET_COMM, bus.now);
	tb_advance(&bus, 1000);
	TEST_ASSERT_FALSE(co_pdo_is_valid(dp->node, CO_PDO_RX, 2));
	devobj_mirror_forget(&mirror);
	TEST_ASSERT_TRUE(devobj_mirror_sync(&mirror, SLAVE));
	TEST_ASSERT_TRUE(co_pdo_is_valid(dp->node, CO_PDO_RX, 2));
	TEST_ASSERT_EQUAL(DEVOBJ_M_FULL, mirror.node[SLAVE].status);
}

void test_mirror_refuses_a_configured_slot_index(void)
{
	co_node_config dc = { .node_id = DAEMON };
	const uint32_t nodes[4] = { 1u << SLAVE, 0, 0, 0 };
	co_od *od = daemon_od(2, 0);
	TEST_ASSERT_EQUAL(
		0, co_od_add_num(od, DEVOBJ_SLOT_RX_INDEX, 0, CO_T_UNSIGNED8, CO_ACC_RW, 0, NULL));
	tb_init(&bus);
	dp = tb_add_node(&bus, &dc, od);
	TEST_ASSERT_EQUAL(0, co_pdo_layout_create(&layout, nodes, 8));
	TEST_ASSERT_EQUAL(-EEXIST, devobj_mirror_create(&mirror, dp->node, layout, nodes, NULL));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_value_integers_by_width);
	RUN_TEST(test_value_reals_booleans_strings);
	RUN_TEST(test_value_unknown_and_asked_types);
	RUN_TEST(test_value_insert_checks);
	RUN_TEST(test_mirror_consumes_every_tpdo_and_produces_the_rpdo);
	RUN_TEST(test_mirror_reports_what_does_not_fit);
	RUN_TEST(test_mirror_leaves_hand_written_cob_ids_alone);
	RUN_TEST(test_mirror_released_on_invalidation_and_after_a_reset);
	RUN_TEST(test_mirror_refuses_a_configured_slot_index);
	return UNITY_END();
}
