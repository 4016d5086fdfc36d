/* SPDX-License-Identifier: MIT */
/*
 * PDO unit tests: one node (id 5) and a scripted peer (the test) on the
 * in-memory bus; the test owns the clock. PDO services of CiA 301
 * §7.2.2, plus mapping edge cases (bit-sized and
 * odd-length entries, dummies, OD limits, hooks with origin PDO).
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/emcy.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sync.h"
#include "tests/unit/support/test_bus.h"

#define NODE 5
#define EMCY_ID (0x80 + NODE)

enum {
	IDX_U16 = 0x2000,
	IDX_U8 = 0x2001,
	IDX_U32 = 0x2002,
	IDX_BOOL = 0x2003,
	IDX_I16 = 0x2004,
	IDX_U24 = 0x2005,
	IDX_NOMAP = 0x2006,
	IDX_STR = 0x2007,
	IDX_LIM = 0x2008,
};

static tb_bus bus;
static tb_port *port;
static co_node *node;
static co_od *od;

/* ---- fixture ---------------------------------------------------------------- */

static co_od *make_od(void)
{
	co_od *o;
	const uint16_t rww_rwr = CO_ACC_RW | CO_ACC_RPDO | CO_ACC_TPDO;

	TEST_ASSERT_EQUAL(0, co_od_create(&o, 256));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_U16, 0, CO_T_UNSIGNED16, rww_rwr, 0x1234, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_U8, 0, CO_T_UNSIGNED8, rww_rwr, 0x56, NULL));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(o, IDX_U32, 0, CO_T_UNSIGNED32, rww_rwr, 0xDEADBEEF, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_BOOL, 0, CO_T_BOOLEAN, rww_rwr, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_I16, 0, CO_T_INTEGER16, rww_rwr, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_U24, 0, CO_T_UNSIGNED24, rww_rwr, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_NOMAP, 0, CO_T_UNSIGNED8, CO_ACC_RW, 0, NULL));
	TEST_ASSERT_EQUAL(
		0, co_od_add_bytes(o, IDX_STR, 0, CO_T_VISIBLE_STRING, rww_rwr, 4, "ab", 2, NULL));
	co_od_entry *lim;
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, IDX_LIM, 0, CO_T_UNSIGNED16, rww_rwr, 50, &lim));
	TEST_ASSERT_EQUAL(0, co_od_entry_set_limits(lim, 0, 100));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_emcy(o, NODE, 8, 0, 0));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_sync(o, 0, 0, 0));
	for (uint16_t n = 1; n <= 8; n++) {
		co_pdo_desc r = { .dir = CO_PDO_RX,
				  .nr = n,
				  .cob_id = CO_PDO_COB_INVALID | (0x200u + n),
				  .tt = 254 };
		co_pdo_desc t = { .dir = CO_PDO_TX,
				  .nr = n,
				  .cob_id = CO_PDO_COB_INVALID | (0x180u + n),
				  .tt = 254 };
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &r));
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &t));
	}
	return o;
}

void setUp(void)
{
	co_node_config cfg = { .node_id = NODE };

	tb_init(&bus);
	od = make_od();
	port = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_NOT_NULL(port);
	node = port->node;
	tb_advance(&bus, 0); /* boot-up, PRE-OPERATIONAL */
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(node));
	tb_log_clear(&bus);
	tb_events_clear(port);
}

void tearDown(void)
{
	tb_fini(&bus);
}

static uint32_t odw(uint16_t index, uint8_t sub, uint64_t v)
{
	return tb_od_write(&bus, node, index, sub, v);
}

static uint64_t odr(uint16_t index, uint8_t sub)
{
	co_od_entry *e = co_od_find(od, index, sub);

	TEST_ASSERT_NOT_NULL(e);
	return co_od_entry_raw(e);
}

/* The CiA 301 5-step sequence, every step must succeed. */
static void pdo_setup(co_pdo_dir dir, uint16_t nr, uint32_t cob, uint8_t tt, uint16_t inhibit,
		      uint16_t event_ms, uint8_t start, uint8_t n, const uint32_t *map)
{
	uint16_t comm = (uint16_t)((dir == CO_PDO_TX ? 0x1800 : 0x1400) + nr - 1);
	uint16_t mapi = (uint16_t)(comm + 0x200);

	TEST_ASSERT_EQUAL_HEX32(0, odw(comm, 1, cob | CO_PDO_COB_INVALID));
	TEST_ASSERT_EQUAL_HEX32(0, odw(mapi, 0, 0));
	for (uint8_t i = 0; i < n; i++)
		TEST_ASSERT_EQUAL_HEX32(0, odw(mapi, (uint8_t)(i + 1), map[i]));
	TEST_ASSERT_EQUAL_HEX32(0, odw(mapi, 0, n));
	TEST_ASSERT_EQUAL_HEX32(0, odw(comm, 2, tt));
	if (dir == CO_PDO_TX) {
		TEST_ASSERT_EQUAL_HEX32(0, odw(comm, 3, inhibit));
		TEST_ASSERT_EQUAL_HEX32(0, odw(comm, 6, start));
	}
	TEST_ASSERT_EQUAL_HEX32(0, odw(comm, 5, event_ms));
	TEST_ASSERT_EQUAL_HEX32(0, odw(comm, 1, cob));
	TEST_ASSERT_TRUE(co_pdo_is_valid(node, dir, nr));
}

static void nmt(uint8_t cs)
{
	co_frame f = tb_frame(0x000, "00 00");
	f.data[0] = cs;
	f.data[1] = NODE;
	tb_send(&bus, &f);
}

static void start_node(void)
{
	nmt(CO_NMT_CS_START);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(node));
	tb_log_clear(&bus);
	tb_events_clear(port);
}

static void sync0(void)
{
	tb_send_hex(&bus, 0x80, "");
}

static void sync1(uint8_t counter)
{
	co_frame f = tb_frame(0x80, "00");
	f.data[0] = counter;
	tb_send(&bus, &f);
}

static void rtr(uint32_t id, uint8_t len)
{
	co_frame f = tb_frame(id, "");
	f.flags = CO_FRAME_RTR;
	f.len = len;
	tb_send(&bus, &f);
}

/* Frames from the node with this id since log index `since`. */
static unsigned count_id(uint32_t id, size_t since)
{
	unsigned n = 0;

	for (size_t i = since; i < tb_log_count(&bus); i++) {
		const co_frame *f = tb_log_at(&bus, i);
		if (f->id == id && bus.log_from[i] == port->idx)
			n++;
	}
	return n;
}

static const co_frame *last_id(uint32_t id)
{
	for (size_t i = tb_log_count(&bus); i-- > 0;) {
		const co_frame *f = tb_log_at(&bus, i);
		if (f->id == id && bus.log_from[i] == port->idx)
			return f;
	}
	return NULL;
}

#define ASSERT_LAST_ID(id, hex)                                             \
	do {                                                                \
		const co_frame *f_ = last_id(id);                           \
		char b_[96];                                                \
		TEST_ASSERT_NOT_NULL_MESSAGE(f_, "no frame with that id");  \
		TEST_ASSERT_TRUE_MESSAGE(tb_frame_is(f_, (id), (hex)),      \
					 tb_frame_str(f_, b_, sizeof(b_))); \
	} while (0)

static const co_event *nth_event(co_event_kind k, unsigned n)
{
	for (size_t i = 0; i < port->n_ev; i++)
		if (port->ev[i].kind == k && n-- == 0)
			return &port->ev[i];
	return NULL;
}

/* ---- valid RPDO ------------------------------------------------------------ */

static void test_rpdo_event_driven_updates_od_and_reports(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U16, 0, 16), CO_PDO_MAP(IDX_U8, 0, 8) };
	const co_event *ev;

	pdo_setup(CO_PDO_RX, 1, 0x205, 254, 0, 0, 0, 2, map);
	TEST_ASSERT_EQUAL(3, co_pdo_length(node, CO_PDO_RX, 1));
	start_node();
	tb_send_hex(&bus, 0x205, "CD AB 7E");
	TEST_ASSERT_EQUAL_HEX64(0xABCD, odr(IDX_U16, 0));
	TEST_ASSERT_EQUAL_HEX64(0x7E, odr(IDX_U8, 0));

	TEST_ASSERT_EQUAL(2, tb_event_count(port, CO_EV_RPDO_OBJECT));
	ev = nth_event(CO_EV_RPDO_OBJECT, 0);
	TEST_ASSERT_EQUAL_HEX16(IDX_U16, ev->u.pdo_obj.index);
	TEST_ASSERT_EQUAL(16, ev->u.pdo_obj.bits);
	TEST_ASSERT_EQUAL(1, ev->u.pdo_obj.nr);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.pdo_obj.abort);
	ev = nth_event(CO_EV_RPDO_OBJECT, 1);
	TEST_ASSERT_EQUAL_HEX16(IDX_U8, ev->u.pdo_obj.index);

	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO));
	ev = tb_last_event(port, CO_EV_RPDO);
	TEST_ASSERT_EQUAL(1, ev->u.pdo.nr);
	TEST_ASSERT_EQUAL(3, ev->u.pdo.len);
	TEST_ASSERT_EQUAL_HEX32(0x205, ev->u.pdo.cob_id);
	TEST_ASSERT_EQUAL_HEX8(0xCD, ev->u.pdo.data[0]);
	TEST_ASSERT_EQUAL_HEX8(0xAB, ev->u.pdo.data[1]);
	TEST_ASSERT_EQUAL_HEX8(0x7E, ev->u.pdo.data[2]);
	TEST_ASSERT_EQUAL(2, ev->u.pdo.n_map);
	TEST_ASSERT_EQUAL_HEX16(IDX_U8, ev->u.pdo.map[1].index);
	TEST_ASSERT_EQUAL(1, co_pdo_get_stats(node)->rx);
}

static uint32_t hook_origin_seen;
static unsigned hook_calls;

static void rec_after_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	hook_origin_seen = a->origin;
	hook_calls++;
}

static void test_rpdo_write_runs_hooks_with_origin_pdo(void)
{
	static const co_od_hooks h = { .after_write = rec_after_write };
	const uint32_t map[] = { CO_PDO_MAP(IDX_U32, 0, 32) };

	hook_calls = 0;
	hook_origin_seen = 99;
	TEST_ASSERT_EQUAL(0, co_od_set_hooks(od, IDX_U32, 0, &h, NULL));
	pdo_setup(CO_PDO_RX, 2, 0x305, 255, 0, 0, 0, 1, map);
	start_node();
	tb_send_hex(&bus, 0x305, "01 02 03 04");
	TEST_ASSERT_EQUAL(1, hook_calls);
	TEST_ASSERT_EQUAL(CO_OD_ORIGIN_PDO, hook_origin_seen);
	TEST_ASSERT_EQUAL_HEX64(0x04030201, odr(IDX_U32, 0));
}

static void test_rpdo_value_outside_limits_is_refused_per_object(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_LIM, 0, 16), CO_PDO_MAP(IDX_U8, 0, 8) };
	const co_event *ev;

	pdo_setup(CO_PDO_RX, 1, 0x205, 254, 0, 0, 0, 2, map);
	start_node();
	tb_send_hex(&bus, 0x205, "C8 00 11"); /* 200 > max 100 */
	TEST_ASSERT_EQUAL_HEX64(50, odr(IDX_LIM, 0));
	TEST_ASSERT_EQUAL_HEX64(0x11, odr(IDX_U8, 0)); /* the other one lands */
	ev = nth_event(CO_EV_RPDO_OBJECT, 0);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH, ev->u.pdo_obj.abort);
	TEST_ASSERT_EQUAL(1, co_pdo_get_stats(node)->od_refused);
}

/* ---- RPDO supervision (CiA 301 §7.5.2.35, §7.5.2.36) -------------------- */

/* Golden EMCY frames of this node (CiA 301 §7.2.7.3.1: code LE, 1001h,
 * manufacturer bytes = RPDO number LE then zeros). 1001h = 11h: generic
 * error and communication error. */
#define EMCY_8210_RPDO3 "10 82 11 03 00 00 00 00"
#define EMCY_8220_RPDO3 "20 82 11 03 00 00 00 00"
#define EMCY_8250_RPDO4 "50 82 11 04 00 00 00 00"
#define EMCY_RESET "00 00 00 00 00 00 00 00"

static void rpdo3_u16_u8(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U16, 0, 16), CO_PDO_MAP(IDX_U8, 0, 8) };

	pdo_setup(CO_PDO_RX, 3, 0x405, 254, 0, 0, 0, 2, map);
	start_node();
}

static void assert_pdo_event(const co_event *ev, uint16_t nr, uint8_t fault, uint8_t len,
			     uint8_t mapped_len)
{
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL(nr, ev->u.pdo.nr);
	TEST_ASSERT_EQUAL_HEX8(fault, ev->u.pdo.fault);
	TEST_ASSERT_EQUAL(len, ev->u.pdo.len);
	TEST_ASSERT_EQUAL(mapped_len, ev->u.pdo.mapped_len);
}

static void test_rpdo_short_frame_not_processed_emcy_8210_once_per_episode(void)
{
	rpdo3_u16_u8();

	tb_send_hex(&bus, 0x405, "CD AB");
	ASSERT_LAST_ID(EMCY_ID, EMCY_8210_RPDO3);
	TEST_ASSERT_EQUAL_HEX64(0x1234, odr(IDX_U16, 0));
	TEST_ASSERT_EQUAL_HEX64(0x56, odr(IDX_U8, 0));
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_RPDO));
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO_LENGTH));
	assert_pdo_event(tb_last_event(port, CO_EV_RPDO_LENGTH), 3, CO_PDO_FAULT_SHORT, 2, 3);
	TEST_ASSERT_EQUAL_HEX32(0x405, tb_last_event(port, CO_EV_RPDO_LENGTH)->u.pdo.cob_id);
	TEST_ASSERT_EQUAL_HEX64(0x11, odr(0x1001, 0));
	TEST_ASSERT_EQUAL(1, odr(0x1003, 0));
	TEST_ASSERT_EQUAL_HEX64(0x00038210, odr(0x1003, 1));

	/* the same episode: counted, no second EMCY, no second event */
	tb_send_hex(&bus, 0x405, "CD");
	tb_send_hex(&bus, 0x405, "");
	TEST_ASSERT_EQUAL(1, count_id(EMCY_ID, 0));
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO_LENGTH));
	TEST_ASSERT_EQUAL(3, co_pdo_get_stats(node)->rx_length);
	TEST_ASSERT_EQUAL(1, odr(0x1003, 0));

	/* a correct frame ends it: error reset, data applied, reported */
	tb_send_hex(&bus, 0x405, "CD AB 01");
	ASSERT_LAST_ID(EMCY_ID, EMCY_RESET);
	TEST_ASSERT_EQUAL(2, count_id(EMCY_ID, 0));
	TEST_ASSERT_EQUAL_HEX64(0xABCD, odr(IDX_U16, 0));
	TEST_ASSERT_EQUAL_HEX64(0x01, odr(IDX_U8, 0));
	TEST_ASSERT_EQUAL_HEX64(0x00, odr(0x1001, 0));
	TEST_ASSERT_FALSE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO_RECOVERED));
	assert_pdo_event(tb_last_event(port, CO_EV_RPDO_RECOVERED), 3, CO_PDO_FAULT_SHORT, 3, 3);

	/* a new episode, a new EMCY */
	tb_send_hex(&bus, 0x405, "CD");
	ASSERT_LAST_ID(EMCY_ID, EMCY_8210_RPDO3);
	TEST_ASSERT_EQUAL(3, count_id(EMCY_ID, 0));
	TEST_ASSERT_EQUAL(2, tb_event_count(port, CO_EV_RPDO_LENGTH));
}

static void test_rpdo_long_frame_uses_leading_bytes_emcy_8220(void)
{
	co_pdo_rpdo_state st;

	rpdo3_u16_u8();

	tb_send_hex(&bus, 0x405, "11 22 33 44");
	ASSERT_LAST_ID(EMCY_ID, EMCY_8220_RPDO3);
	TEST_ASSERT_EQUAL_HEX64(0x2211, odr(IDX_U16, 0));
	TEST_ASSERT_EQUAL_HEX64(0x33, odr(IDX_U8, 0));
	assert_pdo_event(tb_last_event(port, CO_EV_RPDO_LENGTH), 3, CO_PDO_FAULT_LONG, 4, 3);
	TEST_ASSERT_EQUAL(3, tb_last_event(port, CO_EV_RPDO)->u.pdo.len);
	TEST_ASSERT_EQUAL_HEX64(0x00038220, odr(0x1003, 1));
	TEST_ASSERT_EQUAL(0, co_pdo_rpdo_state_get(node, 3, &st));
	TEST_ASSERT_EQUAL_HEX8(CO_PDO_FAULT_LONG, st.faults);
	TEST_ASSERT_EQUAL(3, st.mapped_len);

	/* still processed, no second EMCY */
	tb_send_hex(&bus, 0x405, "55 66 77 88 99");
	TEST_ASSERT_EQUAL_HEX64(0x6655, odr(IDX_U16, 0));
	TEST_ASSERT_EQUAL(1, count_id(EMCY_ID, 0));
	TEST_ASSERT_EQUAL(2, tb_event_count(port, CO_EV_RPDO));

	/* short after long: 8210h begins, 8220h ends, without an error reset
	 * in between (an error remains) */
	tb_send_hex(&bus, 0x405, "01");
	ASSERT_LAST_ID(EMCY_ID, EMCY_8210_RPDO3);
	TEST_ASSERT_EQUAL(2, count_id(EMCY_ID, 0));
	TEST_ASSERT_TRUE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
	TEST_ASSERT_FALSE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH_HIGH));
	assert_pdo_event(tb_last_event(port, CO_EV_RPDO_RECOVERED), 3, CO_PDO_FAULT_LONG, 1, 3);
	TEST_ASSERT_EQUAL_HEX64(0x6655, odr(IDX_U16, 0));

	tb_send_hex(&bus, 0x405, "01 02 03");
	ASSERT_LAST_ID(EMCY_ID, EMCY_RESET);
	TEST_ASSERT_EQUAL(0, co_pdo_rpdo_state_get(node, 3, &st));
	TEST_ASSERT_EQUAL_HEX8(0, st.faults);
	TEST_ASSERT_EQUAL(0, co_emcy_error_register(node));
}

/* Two RPDOs with the same error: 8210h leaves the active list (and the
 * error reset goes out) only when both received a correct frame. */
static void test_rpdo_length_error_shared_by_two_rpdos(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U32, 0, 32) };

	pdo_setup(CO_PDO_RX, 2, 0x305, 254, 0, 0, 0, 1, map);
	rpdo3_u16_u8();
	tb_send_hex(&bus, 0x305, "01");
	tb_send_hex(&bus, 0x405, "01");
	TEST_ASSERT_EQUAL(2, count_id(EMCY_ID, 0)); /* one per episode */
	tb_send_hex(&bus, 0x305, "01 02 03 04");
	TEST_ASSERT_EQUAL(2, count_id(EMCY_ID, 0));
	TEST_ASSERT_TRUE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
	tb_send_hex(&bus, 0x405, "01 02 03");
	TEST_ASSERT_EQUAL(3, count_id(EMCY_ID, 0));
	ASSERT_LAST_ID(EMCY_ID, EMCY_RESET);
}

static void test_rpdo_event_timer_is_a_receive_deadline(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U8, 0, 8) };
	const co_event *ev;

	pdo_setup(CO_PDO_RX, 4, 0x505, 254, 0, 100, 0, 1, map);
	start_node();
	/* CiA 301: monitoring starts with the first frame */
	tb_advance(&bus, 500000);
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_RPDO_TIMEOUT));

	tb_send_hex(&bus, 0x505, "01");
	tb_advance(&bus, 99000);
	tb_send_hex(&bus, 0x505, "02"); /* restarts the timer */
	tb_advance(&bus, 99999);
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_RPDO_TIMEOUT));
	TEST_ASSERT_EQUAL(0, count_id(EMCY_ID, 0));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO_TIMEOUT));
	ev = tb_last_event(port, CO_EV_RPDO_TIMEOUT);
	assert_pdo_event(ev, 4, CO_PDO_FAULT_TIMEOUT, 0, 1);
	TEST_ASSERT_EQUAL(100, ev->u.pdo.event_ms);
	TEST_ASSERT_EQUAL_UINT64(bus.now, ev->now_us);
	ASSERT_LAST_ID(EMCY_ID, EMCY_8250_RPDO4);
	TEST_ASSERT_EQUAL_HEX64(0x00048250, odr(0x1003, 1));
	/* once per episode: re-armed only by the next frame */
	tb_advance(&bus, 1000000);
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO_TIMEOUT));
	TEST_ASSERT_EQUAL(1, count_id(EMCY_ID, 0));
	/* a short frame is not data: the episode goes on */
	tb_send_hex(&bus, 0x505, "");
	TEST_ASSERT_TRUE(co_emcy_is_active(node, CO_EMCY_RPDO_TIMEOUT));
	TEST_ASSERT_EQUAL(2, count_id(EMCY_ID, 0)); /* its own 8210h */
	tb_send_hex(&bus, 0x505, "03");             /* ends both */
	ASSERT_LAST_ID(EMCY_ID, EMCY_RESET);
	TEST_ASSERT_EQUAL(3, count_id(EMCY_ID, 0));
	assert_pdo_event(tb_last_event(port, CO_EV_RPDO_RECOVERED), 4,
			 CO_PDO_FAULT_TIMEOUT | CO_PDO_FAULT_SHORT, 1, 1);
	tb_advance(&bus, 100000);
	TEST_ASSERT_EQUAL(2, tb_event_count(port, CO_EV_RPDO_TIMEOUT));
	ASSERT_LAST_ID(EMCY_ID, EMCY_8250_RPDO4);
	TEST_ASSERT_EQUAL(2, co_pdo_get_stats(node)->rx_timeout);
	/* a longer frame is data: it ends the deadline episode, and the 8220h
	 * it raises keeps the register up (no error reset between) */
	tb_send_hex(&bus, 0x505, "04 05");
	ASSERT_LAST_ID(EMCY_ID, "20 82 11 04 00 00 00 00");
	TEST_ASSERT_FALSE(co_emcy_is_active(node, CO_EMCY_RPDO_TIMEOUT));
	TEST_ASSERT_EQUAL_HEX64(0x04, odr(IDX_U8, 0));
}

/* A reset communication and a PDO made invalid end the episodes: their
 * codes leave the active list. */
static void test_rpdo_episodes_end_with_the_configuration(void)
{
	rpdo3_u16_u8();
	tb_send_hex(&bus, 0x405, "01");
	TEST_ASSERT_TRUE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
	nmt(CO_NMT_CS_ENTER_PREOP);
	TEST_ASSERT_TRUE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH)); /* NMT alone: no */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1402, 1, 0x405 | CO_PDO_COB_INVALID));
	TEST_ASSERT_FALSE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
	ASSERT_LAST_ID(EMCY_ID, EMCY_RESET);
	assert_pdo_event(tb_last_event(port, CO_EV_RPDO_RECOVERED), 3, CO_PDO_FAULT_SHORT, 0, 3);

	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1402, 1, 0x405));
	start_node();
	tb_send_hex(&bus, 0x405, "01");
	TEST_ASSERT_TRUE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
	nmt(CO_NMT_CS_RESET_COMM);
	TEST_ASSERT_FALSE(co_emcy_is_active(node, CO_EMCY_PDO_LENGTH));
}

static void test_rpdo_sync_data_committed_at_next_sync(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U32, 0, 32) };

	pdo_setup(CO_PDO_RX, 5, 0x206, 1, 0, 0, 0, 1, map);
	start_node();
	tb_send_hex(&bus, 0x206, "11 11 11 11");
	tb_send_hex(&bus, 0x206, "44 33 22 11"); /* the latest frame wins */
	TEST_ASSERT_EQUAL_HEX64(0xDEADBEEF, odr(IDX_U32, 0));
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_RPDO));
	sync0();
	TEST_ASSERT_EQUAL_HEX64(0x11223344, odr(IDX_U32, 0));
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO));
	sync0(); /* nothing new: nothing written again */
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_RPDO));
}

static void test_rpdo_sync_outside_window_dropped(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U8, 0, 8) };

	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1007, 0, 2000)); /* 2 ms window */
	pdo_setup(CO_PDO_RX, 5, 0x206, 0, 0, 0, 0, 1, map);
	start_node();
	sync0();
	tb_advance(&bus, 1000);
	tb_send_hex(&bus, 0x206, "21"); /* in the window */
	sync0();
	TEST_ASSERT_EQUAL_HEX64(0x21, odr(IDX_U8, 0));
	tb_advance(&bus, 2001);
	tb_send_hex(&bus, 0x206, "22"); /* too late */
	sync0();
	TEST_ASSERT_EQUAL_HEX64(0x21, odr(IDX_U8, 0));
	TEST_ASSERT_EQUAL(1, co_pdo_get_stats(node)->rx_late);
}

/* ---- synchronous TPDOs ------------------------------------------------------- */

static void test_tpdo_sync_types(void)
{
	const uint32_t m1[] = { CO_PDO_MAP(IDX_U16, 0, 16), CO_PDO_MAP(IDX_U8, 0, 8) };
	const uint32_t m2[] = { CO_PDO_MAP(IDX_U32, 0, 32) };
	const uint32_t m3[] = { CO_PDO_MAP(IDX_U8, 0, 8) };

	pdo_setup(CO_PDO_TX, 1, 0x185, 1, 0, 0, 0, 2, m1);
	pdo_setup(CO_PDO_TX, 2, 0x285, 3, 0, 0, 0, 1, m2);
	pdo_setup(CO_PDO_TX, 3, 0x385, 0, 0, 0, 0, 1, m3);
	start_node();
	for (int i = 1; i <= 6; i++) {
		sync0();
		TEST_ASSERT_EQUAL(i, count_id(0x185, 0));
		TEST_ASSERT_EQUAL(i / 3, count_id(0x285, 0));
	}
	ASSERT_LAST_ID(0x185, "34 12 56");
	ASSERT_LAST_ID(0x285, "EF BE AD DE");
	TEST_ASSERT_EQUAL(0, count_id(0x385, 0)); /* TT 0: no change yet */

	/* TT 0: a change, then the next SYNC; once */
	TEST_ASSERT_EQUAL_HEX32(0, co_od_set_u8(od, IDX_U8, 0, 0x99));
	/* TPDO 1 and 3 map it; only TT 0 (and 254/255) react to changes */
	TEST_ASSERT_EQUAL(1, co_pdo_object_changed(node, IDX_U8, 0, bus.now));
	TEST_ASSERT_EQUAL(0, count_id(0x385, 0)); /* not before the SYNC */
	sync0();
	TEST_ASSERT_EQUAL(1, count_id(0x385, 0));
	ASSERT_LAST_ID(0x385, "99");
	ASSERT_LAST_ID(0x185, "34 12 99"); /* sampled at the SYNC */
	sync0();
	TEST_ASSERT_EQUAL(1, count_id(0x385, 0));
	/* pdo request on TT 0 works like a change */
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_event(node, 3, bus.now));
	sync0();
	TEST_ASSERT_EQUAL(2, count_id(0x385, 0));
}

/* ---- event-driven, inhibit, event timer --------------------------------------- */

/* Bus filter recording when frames with one id went out. */
struct tstamps {
	uint32_t id;
	uint64_t t[64];
	unsigned n;
};

static tb_action stamp_filter(void *ctx, const co_frame *f, int from, uint64_t n)
{
	struct tstamps *ts = ctx;

	(void)from;
	(void)n;
	if (f->id == ts->id && ts->n < 64)
		ts->t[ts->n++] = bus.now;
	return TB_DELIVER;
}

static void test_tpdo_event_inhibit_and_event_timer(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U16, 0, 16) };
	struct tstamps ts = { .id = 0x485 };
	uint64_t t0;
	size_t mark;

	pdo_setup(CO_PDO_TX, 4, 0x485, 254, 500, 0, 0, 1, map);
	start_node();
	bus.filter = stamp_filter;
	bus.filter_ctx = &ts;
	t0 = bus.now;
	/* change storm, one change per ms for 200 ms */
	for (int i = 0; i < 200; i++) {
		co_od_set_u16(od, IDX_U16, 0, (uint16_t)(0x100 + i));
		co_pdo_object_changed(node, IDX_U16, 0, bus.now);
		tb_advance(&bus, 1000);
	}
	/* at t = 0, 50, 100, 150 ms and, for the changes after 150 ms,
	 * at 200 ms when the inhibit time ran out: never closer than 50 ms */
	TEST_ASSERT_EQUAL(5, count_id(0x485, 0));
	TEST_ASSERT_EQUAL(5, ts.n);
	for (unsigned i = 0; i < 5; i++)
		TEST_ASSERT_EQUAL_UINT64(t0 + i * 50000u, ts.t[i]);
	bus.filter = NULL;
	tb_advance(&bus, 1000);
	TEST_ASSERT_EQUAL(5, count_id(0x485, 0));
	ASSERT_LAST_ID(0x485, "C7 01"); /* the latest value, 0x1C7 */
	TEST_ASSERT_TRUE(co_pdo_get_stats(node)->tx_inhibited >= 4);
	tb_advance(&bus, 500000);
	TEST_ASSERT_EQUAL(5, count_id(0x485, 0)); /* no timer: quiet */

	/* event timer 1 s: periodic without any event */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1803, 5, 1000));
	mark = tb_log_count(&bus);
	tb_advance(&bus, 999999);
	TEST_ASSERT_EQUAL(0, count_id(0x485, mark));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(1, count_id(0x485, mark));
	tb_advance(&bus, 2000000);
	TEST_ASSERT_EQUAL(3, count_id(0x485, mark));
	/* an event restarts the period */
	tb_advance(&bus, 400000);
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_event(node, 4, bus.now));
	TEST_ASSERT_EQUAL(4, count_id(0x485, mark));
	tb_advance(&bus, 999999);
	TEST_ASSERT_EQUAL(4, count_id(0x485, mark));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(5, count_id(0x485, mark));
}

/* ---- SYNC start value ----------------------------------------------------------- */

static void test_tpdo_sync_start_value_with_counter(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U8, 0, 8) };
	unsigned sent_at[16] = { 0 };

	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1019, 0, 8));
	pdo_setup(CO_PDO_TX, 5, 0x1C5, 2, 0, 0, 3, 1, map);
	start_node();
	for (uint8_t c = 1; c <= 8; c++) {
		size_t mark = tb_log_count(&bus);
		sync1(c);
		sent_at[c] = count_id(0x1C5, mark);
	}
	/* first at counter 3, then every 2nd */
	TEST_ASSERT_EQUAL(0, sent_at[1]);
	TEST_ASSERT_EQUAL(0, sent_at[2]);
	TEST_ASSERT_EQUAL(1, sent_at[3]);
	TEST_ASSERT_EQUAL(0, sent_at[4]);
	TEST_ASSERT_EQUAL(1, sent_at[5]);
	TEST_ASSERT_EQUAL(0, sent_at[6]);
	TEST_ASSERT_EQUAL(1, sent_at[7]);
	TEST_ASSERT_EQUAL(0, sent_at[8]);
	/* with 1019h > 0 a SYNC without the counter byte is invalid */
	sync0();
	TEST_ASSERT_EQUAL(1, co_sync_get_stats(node)->rx_invalid);
}

/* ---- remapping ------------------------------------------------------------------ */

static void test_remap_sequence_and_aborts(void)
{
	const uint32_t m1[] = { CO_PDO_MAP(IDX_U16, 0, 16) };

	pdo_setup(CO_PDO_TX, 1, 0x185, 1, 0, 0, 0, 1, m1);
	/* valid PDO: mapping frozen */
	TEST_ASSERT_EQUAL_HEX32(CO_PDO_AB_SEQUENCE, odw(0x1A00, 0, 0));
	TEST_ASSERT_EQUAL_HEX32(CO_PDO_AB_SEQUENCE, odw(0x1A00, 2, CO_PDO_MAP(IDX_U8, 0, 8)));
	/* COB-ID change while valid */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1800, 1, 0x186));
	/* step 1: invalidate */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1800, 1, CO_PDO_COB_INVALID | 0x185));
	TEST_ASSERT_FALSE(co_pdo_is_valid(node, CO_PDO_TX, 1));
	/* entries still frozen while sub 0 != 0 */
	TEST_ASSERT_EQUAL_HEX32(CO_PDO_AB_SEQUENCE, odw(0x1A00, 2, CO_PDO_MAP(IDX_U8, 0, 8)));
	/* step 2 */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1A00, 0, 0));
	/* step 3 with the value aborts */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_MAP, odw(0x1A00, 1, CO_PDO_MAP(IDX_NOMAP, 0, 8)));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, odw(0x1A00, 1, CO_PDO_MAP(0x2999, 0, 8)));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_SUB, odw(0x1A00, 1, CO_PDO_MAP(IDX_U8, 7, 8)));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_MAP, odw(0x1A00, 1, CO_PDO_MAP(IDX_U8, 0, 9)));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_MAP,
				odw(0x1A00, 1, CO_PDO_MAP(0x0005, 0, 8))); /* dummy in a TPDO */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1A00, 1, CO_PDO_MAP(IDX_U32, 0, 32)));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1A00, 2, CO_PDO_MAP(IDX_U16, 0, 16)));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1A00, 3, CO_PDO_MAP(IDX_U32, 0, 32)));
	/* step 4: 80 bits do not fit */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_MAP_LEN, odw(0x1A00, 0, 3));
	TEST_ASSERT_EQUAL_HEX64(0, odr(0x1A00, 0));
	/* more entries than exist */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_MAP_LEN, odw(0x1A00, 0, 9));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1A00, 0, 2));
	/* validating with a restricted CAN-ID (SDO response range) fails */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1800, 1, 0x585));
	/* reserved transmission type */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1800, 2, 245));
	/* step 5 */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1800, 1, 0x185));
	TEST_ASSERT_TRUE(co_pdo_is_valid(node, CO_PDO_TX, 1));
	TEST_ASSERT_EQUAL(6, co_pdo_length(node, CO_PDO_TX, 1));
	/* inhibit / start value frozen while valid */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1800, 3, 10));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1800, 6, 1));
	/* RPDO: TT 252/253 do not exist */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1400, 2, 252));

	start_node();
	sync0();
	ASSERT_LAST_ID(0x185, "EF BE AD DE 34 12");
}

/* ---- bit-sized, odd-length and dummy entries ---------------------------------------- */

static void test_bit_and_odd_length_mapping(void)
{
	const uint32_t rmap[] = {
		CO_PDO_MAP(IDX_BOOL, 0, 1),
		CO_PDO_MAP(CO_T_UNSIGNED8, 0, 7), /* dummy: skip 7 bits */
		CO_PDO_MAP(IDX_I16, 0, 12),
		CO_PDO_MAP(IDX_U24, 0, 24),
	};
	const uint32_t tmap[] = {
		CO_PDO_MAP(IDX_BOOL, 0, 1),
		CO_PDO_MAP(IDX_I16, 0, 12),
		CO_PDO_MAP(IDX_U24, 0, 24),
	};
	int16_t i16;

	pdo_setup(CO_PDO_RX, 6, 0x207, 255, 0, 0, 0, 4, rmap);
	pdo_setup(CO_PDO_TX, 6, 0x2C5, 1, 0, 0, 0, 3, tmap);
	TEST_ASSERT_EQUAL(6, co_pdo_length(node, CO_PDO_RX, 6)); /* 44 bits */
	TEST_ASSERT_EQUAL(5, co_pdo_length(node, CO_PDO_TX, 6)); /* 37 bits */
	start_node();
	/* bool 1, dummy 1111111, int12 0xFFE (-2), u24 0xABCDEF */
	tb_send_hex(&bus, 0x207, "FF FE FF DE BC 0A");
	TEST_ASSERT_EQUAL_HEX64(1, odr(IDX_BOOL, 0));
	TEST_ASSERT_EQUAL(0, co_od_get_i16(od, IDX_I16, 0, &i16));
	TEST_ASSERT_EQUAL_INT16(-2, i16); /* sign-extended */
	TEST_ASSERT_EQUAL_HEX64(0xABCDEF, odr(IDX_U24, 0));
	TEST_ASSERT_EQUAL(3, tb_event_count(port, CO_EV_RPDO_OBJECT)); /* no dummy */
	sync0();
	ASSERT_LAST_ID(0x2C5, "FD FF BD 79 15");
}

static void test_string_mapping(void)
{
	const uint32_t rmap[] = { CO_PDO_MAP(IDX_STR, 0, 32) };
	uint8_t buf[8];
	uint32_t len;

	/* strings: whole bytes, up to the capacity (4) */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_MAP, odw(0x1A00, 1, CO_PDO_MAP(IDX_STR, 0, 12)));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_MAP, odw(0x1A00, 1, CO_PDO_MAP(IDX_STR, 0, 40)));
	pdo_setup(CO_PDO_RX, 7, 0x208, 255, 0, 0, 0, 1, rmap);
	start_node();
	tb_send_hex(&bus, 0x208, "77 78 79 7A");
	TEST_ASSERT_EQUAL(0, co_od_get_bytes(od, IDX_STR, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL(4, len);
	TEST_ASSERT_EQUAL_MEMORY("wxyz", buf, 4);
}

/* ---- invalid PDO, pdo request, RTR ------------------------------------------------ */

static void test_invalid_pdo_silent_and_pdo_request_rules(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U8, 0, 8) };

	pdo_setup(CO_PDO_TX, 1, 0x185, 1, 0, 0, 0, 1, map);
	pdo_setup(CO_PDO_TX, 2, 0x285, 254, 0, 0, 0, 1, map);
	start_node();
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1800, 1, CO_PDO_COB_INVALID | 0x185));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1801, 1, CO_PDO_COB_INVALID | 0x285));
	sync0();
	TEST_ASSERT_EQUAL(0, count_id(0x185, 0));
	TEST_ASSERT_EQUAL(-EAGAIN, co_pdo_tpdo_event(node, 2, bus.now));
	TEST_ASSERT_EQUAL(0, co_pdo_object_changed(node, IDX_U8, 0, bus.now));
	TEST_ASSERT_EQUAL(0, count_id(0x285, 0));
	/* request rules */
	TEST_ASSERT_EQUAL(-EPERM, co_pdo_tpdo_event(node, 1, bus.now)); /* TT 1 */
	TEST_ASSERT_EQUAL(-EINVAL, co_pdo_tpdo_event(node, 0, bus.now));
	TEST_ASSERT_EQUAL(-EINVAL, co_pdo_tpdo_event(node, 513, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, co_pdo_tpdo_event(node, 9, bus.now));
	/* valid again: the request goes out at once */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1801, 1, 0x285));
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_event(node, 2, bus.now));
	ASSERT_LAST_ID(0x285, "56");
}

static void test_rtr_answered_only_without_bit30(void)
{
	const uint32_t m16[] = { CO_PDO_MAP(IDX_U16, 0, 16) };
	const uint32_t m8[] = { CO_PDO_MAP(IDX_U8, 0, 8) };

	pdo_setup(CO_PDO_TX, 1, 0x185, 253, 0, 0, 0, 1, m16);
	pdo_setup(CO_PDO_TX, 2, CO_PDO_COB_NO_RTR | 0x285, 253, 0, 0, 0, 1, m8);
	pdo_setup(CO_PDO_TX, 3, 0x385, 252, 0, 0, 0, 1, m16);
	start_node();

	rtr(0x185, 2);
	TEST_ASSERT_EQUAL(1, count_id(0x185, 0));
	ASSERT_LAST_ID(0x185, "34 12");
	rtr(0x285, 1);
	TEST_ASSERT_EQUAL(0, count_id(0x285, 0));

	/* TT 252: sampled at the SYNC, sent on RTR */
	sync0();
	TEST_ASSERT_EQUAL(0, count_id(0x385, 0));
	co_od_set_u16(od, IDX_U16, 0, 0x7777);
	rtr(0x385, 2);
	ASSERT_LAST_ID(0x385, "34 12");
	sync0();
	rtr(0x385, 2);
	ASSERT_LAST_ID(0x385, "77 77");
	TEST_ASSERT_EQUAL(2, count_id(0x385, 0));
	/* TT 253 samples on the RTR itself */
	rtr(0x185, 2);
	ASSERT_LAST_ID(0x185, "77 77");
	/* a sync type cannot be requested by the application */
	TEST_ASSERT_EQUAL(-EPERM, co_pdo_tpdo_event(node, 3, bus.now));
}

/* ---- OPERATIONAL only ----------------------------------------------------------- */

static void test_no_pdo_traffic_outside_operational(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U8, 0, 8) };

	pdo_setup(CO_PDO_RX, 1, 0x205, 254, 0, 0, 0, 1, map);
	pdo_setup(CO_PDO_TX, 1, 0x185, 1, 0, 0, 0, 1, map);
	pdo_setup(CO_PDO_TX, 2, 0x285, 254, 0, 100, 0, 1, map);

	/* PRE-OPERATIONAL */
	tb_send_hex(&bus, 0x205, "01");
	sync0();
	rtr(0x185, 1);
	tb_advance(&bus, 500000);
	TEST_ASSERT_EQUAL_HEX64(0x56, odr(IDX_U8, 0));
	TEST_ASSERT_EQUAL(0, count_id(0x185, 0) + count_id(0x285, 0));
	TEST_ASSERT_EQUAL(-EAGAIN, co_pdo_tpdo_event(node, 2, bus.now));

	/* OPERATIONAL: everything runs, the event timer starts */
	start_node();
	tb_send_hex(&bus, 0x205, "02");
	TEST_ASSERT_EQUAL_HEX64(0x02, odr(IDX_U8, 0));
	sync0();
	TEST_ASSERT_EQUAL(1, count_id(0x185, 0));
	tb_advance(&bus, 100000);
	TEST_ASSERT_EQUAL(1, count_id(0x285, 0));

	/* STOPPED */
	nmt(CO_NMT_CS_STOP);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, co_nmt_get_state(node));
	tb_log_clear(&bus);
	tb_send_hex(&bus, 0x205, "03");
	sync0();
	tb_advance(&bus, 1000000);
	TEST_ASSERT_EQUAL_HEX64(0x02, odr(IDX_U8, 0));
	TEST_ASSERT_EQUAL(0, count_id(0x185, 0) + count_id(0x285, 0));

	/* back to PRE-OPERATIONAL, then OPERATIONAL again */
	nmt(CO_NMT_CS_ENTER_PREOP);
	tb_send_hex(&bus, 0x205, "04");
	TEST_ASSERT_EQUAL_HEX64(0x02, odr(IDX_U8, 0));
	start_node();
	tb_send_hex(&bus, 0x205, "05");
	TEST_ASSERT_EQUAL_HEX64(0x05, odr(IDX_U8, 0));
}

/* ---- reset communication -------------------------------------------------------------- */

static void test_reset_comm_restores_configuration(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U32, 0, 32) };

	pdo_setup(CO_PDO_TX, 1, 0x185, 1, 0, 0, 0, 1, map);
	TEST_ASSERT_EQUAL(4, co_pdo_length(node, CO_PDO_TX, 1));
	nmt(CO_NMT_CS_RESET_COMM);
	tb_advance(&bus, 0);
	/* back to the OD defaults: invalid, nothing mapped */
	TEST_ASSERT_FALSE(co_pdo_is_valid(node, CO_PDO_TX, 1));
	TEST_ASSERT_EQUAL(0, co_pdo_length(node, CO_PDO_TX, 1));
	start_node();
	sync0();
	TEST_ASSERT_EQUAL(0, count_id(0x185, 0));
}

static void test_names(void)
{
	TEST_ASSERT_EQUAL_STRING("sync-acyclic", co_pdo_tt_to_string(0));
	TEST_ASSERT_EQUAL_STRING("sync-cyclic", co_pdo_tt_to_string(240));
	TEST_ASSERT_EQUAL_STRING("reserved", co_pdo_tt_to_string(241));
	TEST_ASSERT_EQUAL_STRING("rtr-sync", co_pdo_tt_to_string(252));
	TEST_ASSERT_EQUAL_STRING("rtr-event", co_pdo_tt_to_string(253));
	TEST_ASSERT_EQUAL_STRING("event-manufacturer", co_pdo_tt_to_string(254));
	TEST_ASSERT_EQUAL_STRING("event-profile", co_pdo_tt_to_string(255));
	TEST_ASSERT_EQUAL_STRING("tpdo", co_pdo_dir_to_string(CO_PDO_TX));
	TEST_ASSERT_EQUAL_STRING("rpdo", co_event_kind_to_string(CO_EV_RPDO));
	TEST_ASSERT_EQUAL_STRING("rpdo-timeout", co_event_kind_to_string(CO_EV_RPDO_TIMEOUT));
	TEST_ASSERT_EQUAL_STRING("sync", co_event_kind_to_string(CO_EV_SYNC));
}

/* ---- scale: 512 + 512 PDOs ------------------------------------------------------------ */

static int null_send(void *ctx, const co_frame *f)
{
	(void)ctx;
	(void)f;
	return 0;
}

static void test_512_tpdos_with_event_timers(void)
{
	co_od *big;
	co_node *n2;
	tb_bus b2;
	tb_port *p2;
	co_node_config cfg = { .node_id = 7, .rx_max = 1200 };
	const uint32_t map[] = { CO_PDO_MAP(IDX_U8, 0, 8) };

	tb_init(&b2);
	TEST_ASSERT_EQUAL(0, co_od_create(&big, 4096));
	TEST_ASSERT_EQUAL(0, co_od_add_num(big, IDX_U8, 0, CO_T_UNSIGNED8,
					   CO_ACC_RW | CO_ACC_TPDO | CO_ACC_RPDO, 1, NULL));
	for (uint16_t n = 1; n <= 512; n++) {
		/* event timers 10..521 ms, all different */
		co_pdo_desc t = { .dir = CO_PDO_TX,
				  .nr = n,
				  .cob_id = CO_PDO_COB_EXT | (0x10000u + n),
				  .tt = 254,
				  .event_ms = (uint16_t)(9 + n),
				  .map_subs = 1,
				  .n_map = 1,
				  .map = map };
		co_pdo_desc r = { .dir = CO_PDO_RX,
				  .nr = n,
				  .cob_id = CO_PDO_COB_EXT | (0x20000u + n),
				  .tt = 254,
				  .map_subs = 1,
				  .n_map = 1,
				  .map = map };
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(big, &t));
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(big, &r));
	}
	/* the default receiver pool (512) is too small: a clear error */
	{
		co_node_config small = { .node_id = 7, .od = big, .send = null_send };
		co_node *x = NULL;
		TEST_ASSERT_EQUAL(-ENOSPC, co_node_create(&x, &small));
		TEST_ASSERT_NULL(x);
	}
	p2 = tb_add_node(&b2, &cfg, big);
	TEST_ASSERT_NOT_NULL(p2);
	n2 = p2->node;
	TEST_ASSERT_EQUAL(512, co_pdo_count(n2, CO_PDO_TX));
	TEST_ASSERT_EQUAL(512, co_pdo_count(n2, CO_PDO_RX));
	tb_advance(&b2, 0);
	TEST_ASSERT_EQUAL(0, co_nmt_local_cmd(n2, CO_NMT_CS_START, b2.now));
	tb_log_clear(&b2);
	/* 1 s: TPDO n sends floor(1000 / (9 + n)) times */
	tb_advance(&b2, 1000000);
	{
		unsigned expect = 0;
		for (unsigned n = 1; n <= 512; n++)
			expect += 1000 / (9 + n);
		TEST_ASSERT_EQUAL(expect, tb_log_count(&b2));
	}
	/* the deadline is the earliest TPDO, not a scan */
	TEST_ASSERT_TRUE(co_node_next_deadline_us(n2) > b2.now);
	TEST_ASSERT_TRUE(co_node_next_deadline_us(n2) <= b2.now + 10000);
	tb_fini(&b2);
}

/* ---- a second sender (co_pdo_set_tx_gate) --------------------------------------- */

struct gate_script {
	uint64_t answer;      /* what CLAIM answers */
	uint64_t wait_answer; /* what WAIT answers */
	unsigned claims, forced, waits, resets;
	uint16_t last_nr;
};

static uint64_t scripted_gate(void *ctx, uint16_t nr, co_pdo_gate_op op, uint64_t now_us)
{
	struct gate_script *g = ctx;

	(void)now_us;
	g->last_nr = nr;
	switch (op) {
	case CO_PDO_GATE_CLAIM:
		g->claims++;
		return g->answer;
	case CO_PDO_GATE_FORCED:
		g->forced++;
		break;
	case CO_PDO_GATE_WAIT:
		g->waits++;
		return g->wait_answer;
	case CO_PDO_GATE_RESET:
		g->resets++;
		break;
	}
	return CO_PDO_GATE_GO;
}

static void test_tx_gate_claim_wait_and_served(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U16, 0, 16) };
	struct gate_script g = { .answer = CO_PDO_GATE_GO };
	uint64_t t0;

	pdo_setup(CO_PDO_TX, 2, 0x282, 254, 10, 0, 0, 1, map); /* inhibit 1 ms */
	start_node();
	co_pdo_set_tx_gate(node, scripted_gate, &g);
	/* GO: sent at once, the gate was asked for TPDO 2 */
	TEST_ASSERT_EQUAL(1, co_pdo_object_changed(node, IDX_U16, 0, bus.now));
	TEST_ASSERT_EQUAL(1, count_id(0x282, 0));
	TEST_ASSERT_EQUAL(1, g.claims);
	TEST_ASSERT_EQUAL(2, g.last_nr);
	/* inside the node's own inhibit time: the gate hears that it waits */
	co_od_set_u16(od, IDX_U16, 0, 0x0102);
	co_pdo_object_changed(node, IDX_U16, 0, bus.now);
	TEST_ASSERT_EQUAL(1, g.waits);
	tb_advance(&bus, 1000);
	TEST_ASSERT_EQUAL(2, count_id(0x282, 0));
	ASSERT_LAST_ID(0x282, "02 01");

	/* the other sender transmitted within the inhibit time: wait until it
	 * says, then send the latest value */
	tb_advance(&bus, 5000);
	t0 = bus.now;
	g.answer = t0 + 700;
	co_od_set_u16(od, IDX_U16, 0, 0x0304);
	co_pdo_object_changed(node, IDX_U16, 0, bus.now);
	TEST_ASSERT_EQUAL(2, count_id(0x282, 0));
	g.answer = CO_PDO_GATE_GO;
	tb_advance(&bus, 699);
	TEST_ASSERT_EQUAL(2, count_id(0x282, 0));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(3, count_id(0x282, 0));
	ASSERT_LAST_ID(0x282, "04 03");

	/* SERVED: the other sender already sent this event's frame */
	tb_advance(&bus, 5000);
	g.answer = CO_PDO_GATE_SERVED;
	co_pdo_object_changed(node, IDX_U16, 0, bus.now);
	tb_advance(&bus, 5000);
	TEST_ASSERT_EQUAL(3, count_id(0x282, 0));

	/* inside the inhibit time, an event the other sender's frame carried
	 * (WAIT answered SERVED) does not wait: nothing more is sent */
	g.answer = CO_PDO_GATE_GO;
	co_pdo_object_changed(node, IDX_U16, 0, bus.now); /* sent, inhibit runs */
	TEST_ASSERT_EQUAL(4, count_id(0x282, 0));
	g.wait_answer = CO_PDO_GATE_SERVED;
	co_pdo_object_changed(node, IDX_U16, 0, bus.now);
	tb_advance(&bus, 5000);
	TEST_ASSERT_EQUAL(4, count_id(0x282, 0));
	g.wait_answer = CO_PDO_GATE_GO;

	/* an RTR answer does not wait: recorded as forced */
	rtr(0x282, 2);
	TEST_ASSERT_EQUAL(5, count_id(0x282, 0));
	TEST_ASSERT_EQUAL(1, g.forced);
	/* leaving OPERATIONAL resets every TPDO: the other sender hears it */
	TEST_ASSERT_EQUAL(0, g.resets);
	nmt(CO_NMT_CS_ENTER_PREOP);
	TEST_ASSERT_EQUAL(8, g.resets);
	/* a reconfiguration resets that TPDO */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1801, 1, 0x282 | CO_PDO_COB_INVALID));
	TEST_ASSERT_EQUAL(9, g.resets);
	TEST_ASSERT_EQUAL(2, g.last_nr);
	co_pdo_set_tx_gate(node, NULL, NULL);
}

static void test_tpdo_sent_by_peer_starts_inhibit_and_event_timer(void)
{
	const uint32_t map[] = { CO_PDO_MAP(IDX_U16, 0, 16) };
	co_pdo_tpdo_state st;
	size_t mark;

	pdo_setup(CO_PDO_TX, 3, 0x383, 254, 20, 10, 0, 1, map); /* 2 ms, timer 10 ms */
	TEST_ASSERT_EQUAL(-EAGAIN, co_pdo_tpdo_sent_by_peer(node, 3, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, co_pdo_tpdo_sent_by_peer(node, 99, bus.now));
	start_node();
	tb_advance(&bus, 3000);
	mark = tb_log_count(&bus);
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_sent_by_peer(node, 3, bus.now - 500));
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_state_get(node, 3, &st));
	TEST_ASSERT_TRUE(st.valid && st.operational);
	TEST_ASSERT_EQUAL_UINT64(bus.now + 1500, st.inhibit_until);
	TEST_ASSERT_EQUAL(254, st.tt);
	TEST_ASSERT_EQUAL(2, st.len);
	TEST_ASSERT_EQUAL_HEX32(0x383, st.cob_id);
	TEST_ASSERT_EQUAL(1, co_pdo_get_stats(node)->tx_by_peer);
	/* an event 1 ms later waits for the end of the peer's inhibit time */
	tb_advance(&bus, 1000);
	co_pdo_object_changed(node, IDX_U16, 0, bus.now);
	TEST_ASSERT_EQUAL(0, count_id(0x383, mark));
	TEST_ASSERT_EQUAL(0, co_pdo_tpdo_state_get(node, 3, &st));
	TEST_ASSERT_TRUE(st.event_pending);
	tb_advance(&bus, 499);
	TEST_ASSERT_EQUAL(0, count_id(0x383, mark));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(1, count_id(0x383, mark));
	/* the event timer runs from the node's own transmission now: 10 ms */
	tb_advance(&bus, 9999);
	TEST_ASSERT_EQUAL(1, count_id(0x383, mark));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(2, count_id(0x383, mark));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_rpdo_event_driven_updates_od_and_reports);
	RUN_TEST(test_rpdo_write_runs_hooks_with_origin_pdo);
	RUN_TEST(test_rpdo_value_outside_limits_is_refused_per_object);
	RUN_TEST(test_rpdo_short_frame_not_processed_emcy_8210_once_per_episode);
	RUN_TEST(test_rpdo_long_frame_uses_leading_bytes_emcy_8220);
	RUN_TEST(test_rpdo_length_error_shared_by_two_rpdos);
	RUN_TEST(test_rpdo_episodes_end_with_the_configuration);
	RUN_TEST(test_rpdo_event_timer_is_a_receive_deadline);
	RUN_TEST(test_rpdo_sync_data_committed_at_next_sync);
	RUN_TEST(test_rpdo_sync_outside_window_dropped);
	RUN_TEST(test_tpdo_sync_types);
	RUN_TEST(test_tpdo_event_inhibit_and_event_timer);
	RUN_TEST(test_tpdo_sync_start_value_with_counter);
	RUN_TEST(test_remap_sequence_and_aborts);
	RUN_TEST(test_bit_and_odd_length_mapping);
	RUN_TEST(test_string_mapping);
	RUN_TEST(test_invalid_pdo_silent_and_pdo_request_rules);
	RUN_TEST(test_rtr_answered_only_without_bit30);
	RUN_TEST(test_no_pdo_traffic_outside_operational);
	RUN_TEST(test_reset_comm_restores_configuration);
	RUN_TEST(test_names);
	RUN_TEST(test_512_tpdos_with_event_timers);
	RUN_TEST(test_tx_gate_claim_wait_and_served);
	RUN_TEST(test_tpdo_sent_by_peer_starts_inhibit_and_event_timer);
	return UNITY_END();
}
