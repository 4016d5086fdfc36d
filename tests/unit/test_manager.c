/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-2 manager (core/manager.c) against slaves built from the core
 * itself on the in-memory bus: NMT start-up per 1F80h bit, the network boot,
 * the boot slave process and its status letters, after-boot supervision,
 * Request NMT (1F82h), 1F25h, diagnostics (CiA 302-2).
 */
#include <errno.h>
#include <string.h>

#include "core/commfault.h"
#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "tests/unit/support/mgr_fixture.h"
#include "unity.h"

#define MS 1000ull
#define S 1000000ull
#define MASTER CO_MGR_1F80_MASTER
#define SLAVE_BOOT (CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT)
#define MANDATORY (SLAVE_BOOT | CO_MGR_1F81_MANDATORY)
#define KEEP_ALIVE CO_MGR_1F81_KEEP_ALIVE

static mf f;

void setUp(void) {}
void tearDown(void)
{
	mf_fini(&f);
}

static uint8_t mstate(void)
{
	return co_manager_state(f.mgr);
}

static uint8_t hb_of(tb_port *p)
{
	return co_nmt_get_state(p->node);
}

/* Standard line: manager + slaves 2 (mandatory) and 3 (optional) with
 * heartbeats of 100 ms supervised at 300 ms, identity fully checked. */
static void line_2_3_hb(uint32_t f80, uint16_t hb3)
{
	mf_init(&f, f80, 4);
	mf_slave(&f, 2, 100);
	mf_slave(&f, 3, hb3);
	mf_assign(&f, 2, MANDATORY, 300);
	mf_assign(&f, 3, SLAVE_BOOT, 300);
	mf_expect(&f, 2, MF_DEVICE_TYPE, MF_VENDOR, MF_PRODUCT, MF_REVISION, 1002);
	mf_expect(&f, 3, MF_DEVICE_TYPE, MF_VENDOR, MF_PRODUCT, MF_REVISION, 1003);
	co_od_set_u32(f.mp->od, 0x1F89, 0, 5000);
	tb_advance(&f.bus, 10 * MS); /* the devices were powered first */
}

static void line_2_3(uint32_t f80)
{
	line_2_3_hb(f80, 100);
}

/* ---- the network boot ------------------------------------------------------------ */

/* Node 2 mandatory, 3 optional -> both booted, started, network up. */
static void test_s44_two_nodes_boot_and_start(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "82 00")); /* reset comm all */
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 2, CO_MGR_STEP_START, 0));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 3, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_UINT(1, mf_boot_count(&f, 2, CO_MGR_STEP_SERIAL, 0));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(f.mp->node));
	TEST_ASSERT_TRUE(mf_went_through(&f, CO_MGR_RESETTING));
	TEST_ASSERT_TRUE(mf_went_through(&f, CO_MGR_BOOTING));
	uint8_t fl = co_manager_flags(f.mgr);
	TEST_ASSERT_EQUAL_HEX8(CO_MGR_F_SLAVE_OPERATIONAL | CO_MGR_F_MANAGER_OPERATIONAL, fl);
	const co_mgr_node_diag *d = co_manager_node_diag(f.mgr, 2);
	TEST_ASSERT_TRUE(d->booted);
	TEST_ASSERT_EQUAL_UINT32(1, d->boot_count);
	TEST_ASSERT_TRUE(d->boot_time_us > 0 && d->boot_time_us < 1 * S);
}

/* 1F84h mismatch on the mandatory node -> C, network not started. */
static void test_s45_device_type_mismatch_C(void)
{
	line_2_3(MASTER);
	co_od_set_u32(f.mp->od, 0x1F84, 2, 0x12345678);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 7 * S);
	const co_ev_mgr *e = mf_boot(&f, 2, CO_MGR_STEP_DEVICE_TYPE, 'C');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(MF_DEVICE_TYPE, e->value);
	TEST_ASSERT_EQUAL_HEX32(0x12345678, e->expected);
	TEST_ASSERT_EQUAL_HEX16(0x1000, e->index);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01"));
	TEST_ASSERT_NOT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_TRUE(co_manager_flags(f.mgr) & CO_MGR_F_MANDATORY_MISSING);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 2, CO_MGR_STEP_BOOT_TIME, 'C'));
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	co_mgr_diag dg;
	co_manager_get_diag(f.mgr, &dg);
	TEST_ASSERT_TRUE(co_mgr_bit(&dg.mismatch, 2));
	TEST_ASSERT_FALSE(co_mgr_bit(&dg.mismatch, 3));
	TEST_ASSERT_EQUAL_UINT8(2, dg.first_error_node);
	TEST_ASSERT_EQUAL('C', dg.first_error_status);
}

/* 1F85h = 0 -> no SDO read of 1018h:1 on the bus. */
static void test_s46_zero_expected_not_read(void)
{
	line_2_3(MASTER);
	co_od_set_u32(f.mp->od, 0x1F85, 2, 0);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x602, "40 18 10 01"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x603, "40 18 10 01"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x602, "40 18 10 02"));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
}

/* A silent mandatory node: 1000h retried every second until 1F89h
 * runs out -> B, network not started; when it shows up it is booted and
 * the network starts. */
static void test_s47_silent_mandatory_B_then_late(void)
{
	line_2_3(MASTER);
	mf_assign(&f, 4, MANDATORY, 0);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 4 * S);
	TEST_ASSERT_EQUAL(CO_MGR_WAIT_MANDATORY, mstate());
	unsigned reads = mf_sent(&f, 0x604, "40 00 10 00");
	TEST_ASSERT_TRUE_MESSAGE(reads >= 3 && reads <= 4, "1000h retried every second");
	const co_ev_mgr *e = mf_boot(&f, 4, CO_MGR_STEP_DEVICE_TYPE, 'B');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, e->abort);
	/* repeated identical failures are reported once */
	TEST_ASSERT_EQUAL_UINT(1, mf_boot_count(&f, 4, CO_MGR_STEP_DEVICE_TYPE, 'B'));
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	e = mf_boot(&f, 4, CO_MGR_STEP_BOOT_TIME, 'B');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, e->abort);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01"));
	TEST_ASSERT_EQUAL(CO_MGR_NODE_MISSING, co_manager_node_nmt_state(f.mgr, 4));
	/* the node's diagnostics keep the failing step, not the boot time */
	TEST_ASSERT_EQUAL('B', co_manager_node_diag(f.mgr, 4)->status);
	TEST_ASSERT_EQUAL_HEX16(0x1000, co_manager_node_diag(f.mgr, 4)->index);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, co_manager_node_diag(f.mgr, 4)->abort);
	/* no more retries after the boot time */
	reads = mf_sent(&f, 0x604, "40 00 10 00");
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL_UINT(reads, mf_sent(&f, 0x604, "40 00 10 00"));
	/* it appears: boot-up -> booted -> the network starts */
	mf_slave(&f, 4, 100);
	mf_assign(&f, 4, MANDATORY, 300);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_NOT_NULL(mf_node_ev(&f, 4, CO_MGR_NODE_LATE));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 4, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 3));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	/* the line's transitions, in order (repeats = flag changes) */
	static const uint8_t want[] = { CO_MGR_RESETTING, CO_MGR_BOOTING, CO_MGR_WAIT_MANDATORY,
					CO_MGR_BOOTED, CO_MGR_OPERATIONAL };
	unsigned k = 0;
	for (unsigned i = 0; i < f.n_ev; i++) {
		if (f.ev[i].kind != CO_EV_MGR_STATE)
			continue;
		uint8_t st = f.ev[i].u.mgr.state;
		if (k && st == want[k - 1])
			continue;
		TEST_ASSERT_TRUE_MESSAGE(k < sizeof(want), "too many transitions");
		TEST_ASSERT_EQUAL_STRING(co_mgr_state_to_string(want[k]),
					 co_mgr_state_to_string(st));
		TEST_ASSERT_EQUAL_UINT8(k ? want[k - 1] : CO_MGR_SLAVE, f.ev[i].u.mgr.prev);
		k++;
	}
	TEST_ASSERT_EQUAL_UINT(sizeof(want), k);
}

/* 48 (302-3 hook): the configure step waits for its outcome. */
static int cfg_calls;
static int configure_pending(void *ctx, uint8_t node, uint64_t now)
{
	(void)ctx;
	(void)node;
	(void)now;
	cfg_calls++;
	return 1;
}

static void test_s48_configure_hook_then_start(void)
{
	co_manager_config c = { .sdo_timeout_ms = 100,
				.reset_wait_ms = 500,
				.configure = configure_pending };
	line_2_3(MASTER);
	cfg_calls = 0;
	mf_start(&f, &c);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_INT(2, cfg_calls);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTING, mstate());
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01"));
	TEST_ASSERT_EQUAL_INT(0, co_manager_configure_done(f.mgr, 2, 0, 0, 0, 0, f.bus.now));
	TEST_ASSERT_EQUAL_INT(
		0, co_manager_configure_done(f.mgr, 3, 0x06020000, 0x2000, 1, 4, f.bus.now));
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_manager_configure_done(f.mgr, 3, 0, 0, 0, 0, f.bus.now));
	tb_advance(&f.bus, 1 * S);
	const co_ev_mgr *e = mf_boot(&f, 3, CO_MGR_STEP_CONFIGURE, 'J');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(0x06020000, e->abort);
	TEST_ASSERT_EQUAL_HEX16(0x2000, e->index);
	TEST_ASSERT_EQUAL_UINT8(1, e->sub);
	TEST_ASSERT_EQUAL_UINT32(4, e->value); /* the concise DCF entry */
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 2, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* Keep-alive on an operational node: no reset comm to it, L. */
static void test_s49_keep_alive_operational_not_reset_L(void)
{
	line_2_3(MASTER);
	mf_assign(&f, 2, MANDATORY | KEEP_ALIVE, 300);
	tb_advance(&f.bus, 10 * MS); /* slaves boot */
	co_nmt_local_cmd(f.bus.port[1].node, CO_NMT_CS_START, f.bus.now);
	tb_advance(&f.bus, 200 * MS); /* its heartbeat says 05 */
	tb_log_clear(&f.bus);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "82 00"));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "82 02"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "82 03"));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 2, CO_MGR_STEP_KEEP_ALIVE, 'L'));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 2, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 02"));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	/* L is not a failure */
	TEST_ASSERT_EQUAL(0, co_manager_node_diag(f.mgr, 2)->status);
}

/* 1F80h bit 2 -> booted, nothing started until the application. */
static void test_s50_bit2_waits_for_application(void)
{
	line_2_3(MASTER | CO_MGR_1F80_NO_SELF_START);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01"));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(f.mp->node));
	TEST_ASSERT_EQUAL_INT(0, co_manager_start_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 100 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(f.mp->node));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* Mandatory heartbeat lost: bit 6 -> stop all; bit 4 -> reset all. */
static void node2_goes_silent(void)
{
	f.bus.port[1].deliver = false;
	co_hb_producer_set(f.bus.port[1].node, 0, f.bus.now);
	tb_advance(&f.bus, 500 * MS);
	TEST_ASSERT_NOT_NULL(mf_node_ev(&f, 2, CO_MGR_NODE_LOST));
}

static void lose_node2(void)
{
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	node2_goes_silent();
}

static void test_s51_bit6_stop_all(void)
{
	line_2_3(MASTER | CO_MGR_1F80_STOP_ALL_ON_ERROR);
	lose_node2();
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "02 00"));
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL('E', co_manager_node_diag(f.mgr, 2)->status);
}

static void test_s51_bit4_reset_all(void)
{
	line_2_3(MASTER | CO_MGR_1F80_RESET_ALL_ON_ERROR);
	lose_node2();
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "81 00"));
	TEST_ASSERT_NOT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	/* the manager's own node left OPERATIONAL too */
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(f.mp->node));
	/* node 2 comes back: the network boots again and starts */
	f.bus.port[1].deliver = true;
	co_hb_producer_set(f.bus.port[1].node, 100, f.bus.now);
	co_nmt_local_cmd(f.bus.port[1].node, CO_NMT_CS_RESET_COMM, f.bus.now);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 2)->boot_count);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(f.mp->node));
}

/* An optional node's loss is handled alone: reset comm of that node. */
static void test_optional_loss_handled_alone_E(void)
{
	line_2_3(MASTER | CO_MGR_1F80_STOP_ALL_ON_ERROR);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	co_hb_producer_set(f.bus.port[2].node, 0, f.bus.now);
	tb_advance(&f.bus, 500 * MS);
	const co_ev_mgr *e = mf_node_ev(&f, 3, CO_MGR_NODE_LOST);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT32('E', e->value);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "02 00"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "82 03"));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	/* its reset brought it back (1017h default 100 ms): booted again */
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 3)->boot_count);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* ---- status letters ------------------------------------------------------------------ */

static void test_status_A_not_assigned(void)
{
	line_2_3(MASTER);
	mf_slave(&f, 5, 100);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_node(f.mgr, 5, f.bus.now));
	const co_ev_mgr *e = mf_boot(&f, 5, CO_MGR_STEP_ASSIGNMENT, 'A');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1F81, e->index);
	TEST_ASSERT_EQUAL_UINT8(5, e->sub);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x605, ""));
}

static void identity_letter(uint16_t obj, uint8_t sub, char letter, int step)
{
	line_2_3(MASTER);
	co_od_set_u32(f.mp->od, obj, 3, 0xBAD);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 3 * S);
	const co_ev_mgr *e = mf_boot(&f, 3, step, letter);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1018, e->index);
	TEST_ASSERT_EQUAL_UINT8(sub, e->sub);
	TEST_ASSERT_EQUAL_HEX32(0xBAD, e->expected);
	/* the optional node is not started, the others are */
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_TRUE(co_manager_flags(f.mgr) & CO_MGR_F_OPTIONAL_MISSING);
	/* a wrong device is not polled again and again */
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x603, "40 00 10 00"));
}

static void test_status_D_vendor(void)
{
	identity_letter(0x1F85, 1, 'D', CO_MGR_STEP_VENDOR);
}
static void test_status_M_product(void)
{
	identity_letter(0x1F86, 2, 'M', CO_MGR_STEP_PRODUCT);
}
static void test_status_N_revision(void)
{
	identity_letter(0x1F87, 3, 'N', CO_MGR_STEP_REVISION);
}
static void test_status_O_serial(void)
{
	identity_letter(0x1F88, 4, 'O', CO_MGR_STEP_SERIAL);
}

/* An optional node that never answers is retried for ever. */
static void test_status_B_optional_retried(void)
{
	line_2_3(MASTER);
	mf_assign(&f, 9, SLAVE_BOOT, 0);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 12 * S);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 9, CO_MGR_STEP_DEVICE_TYPE, 'B'));
	TEST_ASSERT_TRUE(mf_sent(&f, 0x609, "40 00 10 00") >= 10);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_TRUE(co_manager_flags(f.mgr) & CO_MGR_F_OPTIONAL_MISSING);
}

/* K: heartbeat consumer configured, the slave sends none. */
static void test_status_K_no_heartbeat(void)
{
	line_2_3_hb(MASTER, 0);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	const co_ev_mgr *e = mf_boot(&f, 3, CO_MGR_STEP_ERRCTRL, 'K');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1016, e->index);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* F: guarding from 1F81h (guard time 100 ms, factor 3); the slave's
 * answers are lost on the way. */
static tb_action drop_guard_answers(void *ctx, const co_frame *fr, int from, uint64_t n)
{
	(void)ctx;
	(void)n;
	return from == 2 && fr->id == 0x703 ? TB_DROP : TB_DELIVER;
}

static void test_status_F_guarding(void)
{
	line_2_3_hb(MASTER, 0);
	mf_assign(&f, 3, SLAVE_BOOT | 3u << 8 | 100u << 16, 0);
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1016, 3, 0));
	f.bus.filter = drop_guard_answers;
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	const co_ev_mgr *e = mf_boot(&f, 3, CO_MGR_STEP_ERRCTRL, 'F');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1F81, e->index);
	TEST_ASSERT_EQUAL_UINT8(3, e->sub);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* Guarding that works: a slave without heartbeat answers the RTRs. */
static void test_guarding_started(void)
{
	line_2_3_hb(MASTER, 0);
	mf_assign(&f, 3, SLAVE_BOOT | 3u << 8 | 100u << 16, 0);
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1016, 3, 0));
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 3, CO_MGR_STEP_ERRCTRL, 0));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 3, CO_MGR_STEP_START, 0));
	TEST_ASSERT_TRUE(mf_sent(&f, 0x703, "") > 0); /* RTRs */
}

/* ---- 1F80h bits ----------------------------------------------------------------- */

static void test_1f80_bit0_clear_plain_slave(void)
{
	line_2_3(0);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_SLAVE, mstate());
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, ""));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x602, ""));
	/* bit 2 clear: the slave starts itself */
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(f.mp->node));
	TEST_ASSERT_EQUAL_INT(-EPERM, co_manager_boot_network(f.mgr, f.bus.now));
	/* and obeys NMT from the bus */
	tb_send_hex(&f.bus, 0x000, "02 01");
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, co_nmt_get_state(f.mp->node));
}

static void test_1f80_bit1_one_broadcast(void)
{
	line_2_3(MASTER | CO_MGR_1F80_START_ALL);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "01 00"));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 02"));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 03"));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
}

static void test_1f80_bit1_clear_one_by_one(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 00"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "01 02"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "01 03"));
}

static void test_1f80_bit3_application_starts_slaves(void)
{
	line_2_3(MASTER | CO_MGR_1F80_APP_STARTS_SLAVES);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01"));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 1));
	/* the application starts a node through Request NMT */
	TEST_ASSERT_EQUAL_INT(0, co_manager_request_nmt(f.mgr, 2, CO_MGR_REQ_START, f.bus.now));
	tb_advance(&f.bus, 10 * MS);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* bit 4/6 clear: a mandatory node's loss is handled alone. */
static void test_1f80_bits46_clear_node_alone(void)
{
	line_2_3(MASTER);
	lose_node2();
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "02 00"));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "81 00"));
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "82 02"));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_TRUE(co_manager_flags(f.mgr) & CO_MGR_F_MANDATORY_MISSING);
}

/* ---- parallel boot and the channel pool ------------------------------------------ */

static void test_parallel_boot_bounded_by_pool(void)
{
	mf_init(&f, MASTER, 2);
	for (uint8_t id = 2; id <= 5; id++) {
		mf_slave(&f, id, 100);
		mf_assign(&f, id, SLAVE_BOOT, 300);
		mf_expect(&f, id, MF_DEVICE_TYPE, MF_VENDOR, 0, 0, 0);
	}
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	for (uint8_t id = 2; id <= 5; id++)
		TEST_ASSERT_NOT_NULL(mf_boot(&f, id, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_UINT(2, mf_max_sdo_in_flight(&f));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
}

/* ---- after the boot --------------------------------------------------------------- */

static void test_unexpected_node_reported_once(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	mf_slave(&f, 7, 100);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_UINT(1, mf_node_count(&f, 7, CO_MGR_NODE_UNEXPECTED));
	TEST_ASSERT_TRUE(co_manager_flags(f.mgr) & CO_MGR_F_OPTIONAL_MISSING);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x607, ""));
}

static void test_own_node_id_is_fatal(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	tb_send_hex(&f.bus, 0x701, "05");
	TEST_ASSERT_EQUAL(CO_MGR_FATAL, mstate());
	TEST_ASSERT_NOT_NULL(mf_node_ev(&f, MF_MANAGER_ID, CO_MGR_NODE_OWN_ID));
	TEST_ASSERT_EQUAL_HEX32(0x701, mf_node_ev(&f, MF_MANAGER_ID, CO_MGR_NODE_OWN_ID)->value);
	TEST_ASSERT_EQUAL_INT(-EPERM, co_manager_boot_node(f.mgr, 2, f.bus.now));
	/* re-init leaves FATAL */
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
}

/* The conflict ends by itself: while the other device keeps sending, the
 * line stays fatal; after the quiet time without its frames the network
 * is booted again; a later frame is a new episode, reported again. */
static void test_own_node_id_conflict_recovers_after_silence(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	tb_send_hex(&f.bus, 0x701, "05");
	TEST_ASSERT_EQUAL(CO_MGR_FATAL, mstate());
	for (unsigned i = 0; i < 8; i++) {
		tb_advance(&f.bus, 1 * S);
		tb_send_hex(&f.bus, 0x701, "05");
	}
	TEST_ASSERT_EQUAL(CO_MGR_FATAL, mstate());
	/* the quiet time (5 s) after the last frame, less a little: fatal */
	tb_advance(&f.bus, CO_COMMFAULT_ID_COLLISION_QUIET_MS * 1000u - 1000u);
	TEST_ASSERT_EQUAL(CO_MGR_FATAL, mstate());
	tb_advance(&f.bus, 1000u);
	TEST_ASSERT_NOT_EQUAL(CO_MGR_FATAL, mstate());
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_UINT(1, mf_node_count(&f, MF_MANAGER_ID, CO_MGR_NODE_OWN_ID));
	/* a new episode: fatal and reported again */
	tb_send_hex(&f.bus, 0x701, "7F");
	TEST_ASSERT_EQUAL(CO_MGR_FATAL, mstate());
	TEST_ASSERT_EQUAL_UINT(2, mf_node_count(&f, MF_MANAGER_ID, CO_MGR_NODE_OWN_ID));
	co_mgr_diag d;
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_EQUAL_UINT32(2, d.duplicates);
}

/* EMCY and SDO answers on the manager's own identities (081h, 581h) are
 * frames anyone can send: reported once per kind, counted each time, and
 * the boot goes on to the end. */
static void test_own_id_emcy_and_sdo_answer_reported_boot_goes_on(void)
{
	co_mgr_diag d;
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 1 * MS);
	tb_send_hex(&f.bus, 0x080 + MF_MANAGER_ID, "00 81 11 00 00 00 00 00");
	tb_send_hex(&f.bus, 0x580 + MF_MANAGER_ID, "43 00 10 00 94 01 04 00");
	tb_send_hex(&f.bus, 0x080 + MF_MANAGER_ID, "00 81 11 00 00 00 00 00");
	TEST_ASSERT_NOT_EQUAL(CO_MGR_FATAL, mstate());
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_FALSE(mf_went_through(&f, CO_MGR_FATAL));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 2, CO_MGR_STEP_START, 0));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 3, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_UINT(2, mf_node_count(&f, MF_MANAGER_ID, CO_MGR_NODE_OWN_ID));
	unsigned emcy = 0, sdo = 0;
	for (unsigned i = 0; i < f.n_ev; i++) {
		const co_ev_mgr *e = &f.ev[i].u.mgr;
		if (f.ev[i].kind != CO_EV_MGR_NODE || e->what != CO_MGR_NODE_OWN_ID)
			continue;
		emcy += e->value == 0x080 + MF_MANAGER_ID;
		sdo += e->value == 0x580 + MF_MANAGER_ID;
	}
	TEST_ASSERT_EQUAL_UINT(1, emcy);
	TEST_ASSERT_EQUAL_UINT(1, sdo);
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_EQUAL_UINT32(3, d.own_id_frames);
	TEST_ASSERT_EQUAL_UINT32(0, d.duplicates);
	/* supervision goes on: node 3 falls silent and is reported lost */
	co_hb_producer_set(f.bus.port[2].node, 0, f.bus.now);
	tb_advance(&f.bus, 500 * MS);
	TEST_ASSERT_NOT_NULL(mf_node_ev(&f, 3, CO_MGR_NODE_LOST));
}

/* A remote request on 701h is a guarding request to the manager and a
 * 701h frame that is no error-control message shows no device: neither
 * stops the line. */
static void test_own_id_guarding_request_and_malformed_heartbeat_not_fatal(void)
{
	co_frame rtr;
	co_mgr_diag d;
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	co_frame_init(&rtr, 0x700 + MF_MANAGER_ID, 1);
	rtr.flags |= CO_FRAME_RTR;
	tb_send(&f.bus, &rtr);
	tb_send_hex(&f.bus, 0x700 + MF_MANAGER_ID, "05 00");
	tb_send_hex(&f.bus, 0x700 + MF_MANAGER_ID, "42");
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_EQUAL_UINT32(2, d.own_id_frames);
	TEST_ASSERT_EQUAL_UINT(1, mf_node_count(&f, MF_MANAGER_ID, CO_MGR_NODE_OWN_ID));
}

static void test_nmt_to_manager_ignored_and_counted(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	tb_send_hex(&f.bus, 0x000, "02 01");
	tb_send_hex(&f.bus, 0x000, "81 00");
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(f.mp->node));
	co_mgr_diag d;
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_EQUAL_UINT32(2, d.nmt_ignored);
	const co_ev_mgr *e = mf_node_ev(&f, MF_MANAGER_ID, CO_MGR_NODE_NMT_IGNORED);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT32(0x81, e->value);
}

static void test_nmt_to_manager_accepted_when_configured(void)
{
	co_manager_config c = { .sdo_timeout_ms = 100,
				.reset_wait_ms = 500,
				.accept_remote_nmt = true };
	line_2_3(MASTER);
	mf_start(&f, &c);
	tb_advance(&f.bus, 2 * S);
	tb_send_hex(&f.bus, 0x000, "02 01");
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, co_nmt_get_state(f.mp->node));
}

static void test_rebooted_node_boots_again(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	co_nmt_local_cmd(f.bus.port[2].node, CO_NMT_CS_RESET_NODE, f.bus.now);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 3)->boot_count);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL_UINT(0, mf_node_count(&f, 3, CO_MGR_NODE_DUPLICATE));
	TEST_ASSERT_EQUAL_UINT(0, mf_node_count(&f, 3, CO_MGR_NODE_LATE));
}

/* A boot-up, then heartbeats saying "operational" though nobody started
 * it: a second device answers on that node-ID. */
static void test_duplicate_node_id(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	tb_send_hex(&f.bus, 0x703, "00");
	tb_advance(&f.bus, 150 * MS); /* the first device's heartbeat: 05 */
	TEST_ASSERT_EQUAL_UINT(1, mf_node_count(&f, 3, CO_MGR_NODE_DUPLICATE));
}

/* A second device with node 3's ID answers every SDO request too: two
 * answers to one request are reported (once); the boot is not disturbed
 * by the extra answers. */
static void test_duplicate_node_id_two_sdo_answers(void)
{
	mf_init(&f, MASTER, 4);
	mf_slave(&f, 2, 100);
	mf_slave(&f, 3, 100);
	mf_slave(&f, 3, 0); /* the twin: no heartbeat, same answers */
	mf_assign(&f, 2, MANDATORY, 300);
	mf_assign(&f, 3, SLAVE_BOOT, 300);
	mf_expect(&f, 3, MF_DEVICE_TYPE, MF_VENDOR, 0, 0, 0);
	tb_advance(&f.bus, 10 * MS);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	const co_ev_mgr *e = mf_node_ev(&f, 3, CO_MGR_NODE_DUPLICATE);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(CO_MGR_DUP_SDO_ANSWERS, e->value);
	TEST_ASSERT_EQUAL_UINT(1, mf_node_count(&f, 3, CO_MGR_NODE_DUPLICATE));
	TEST_ASSERT_EQUAL_UINT(0, mf_node_count(&f, 2, CO_MGR_NODE_DUPLICATE));
	co_mgr_diag d;
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_EQUAL_UINT32(1, d.duplicates);
	TEST_ASSERT_TRUE(co_manager_node_diag(f.mgr, 3)->booted);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
}

static void test_scan_finds_missing_node(void)
{
	co_manager_config c = { .sdo_timeout_ms = 100, .reset_wait_ms = 500, .scan_ms = 2000 };
	line_2_3(MASTER);
	mf_assign(&f, 2, MANDATORY, 300);
	f.bus.port[2].deliver = false; /* node 3 deaf: no boot-up seen later */
	mf_assign(&f, 3, CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_MANDATORY, 300);
	co_od_set_u32(f.mp->od, 0x1F89, 0, 1000);
	mf_start(&f, &c);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	size_t before = mf_sent(&f, 0x603, "40 00 10 00");
	f.bus.port[2].deliver = true;
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_TRUE(mf_sent(&f, 0x603, "40 00 10 00") > before);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
}

static void test_keep_op_restarts_node(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	co_manager_set_keep_op(f.mgr, 3, true);
	tb_advance(&f.bus, 2 * S);
	tb_send_hex(&f.bus, 0x000, "02 03"); /* somebody stops node 3 */
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL_UINT(2, mf_sent(&f, 0x000, "01 03"));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
	TEST_ASSERT_NOT_NULL(mf_node_ev(&f, 3, CO_MGR_NODE_KEEP_OP));
	/* node 2 has no KEEP_OP: stays stopped */
	tb_send_hex(&f.bus, 0x000, "02 02");
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 1));
	/* a stop the manager was asked for is not undone */
	co_manager_request_nmt(f.mgr, 3, CO_MGR_REQ_STOP, f.bus.now);
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 2));
}

/* The network runs, nodes 2 and 3 booted and in these NMT states. */
static void assert_network_runs(uint8_t nmt2, uint8_t nmt3)
{
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_TRUE(co_manager_node_diag(f.mgr, 2)->booted);
	TEST_ASSERT_TRUE(co_manager_node_diag(f.mgr, 3)->booted);
	TEST_ASSERT_EQUAL_HEX8(nmt2, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(nmt3, hb_of(f.bus.port + 2));
}

/* Per node, the state after its boot: node 2 stopped, node 3 left
 * pre-operational; neither gets a start, the network runs. */
static void test_target_state_per_node(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	TEST_ASSERT_EQUAL_INT(0, co_manager_set_target_state(f.mgr, 2, CO_NMT_STOPPED));
	TEST_ASSERT_EQUAL_INT(0, co_manager_set_target_state(f.mgr, 3, CO_NMT_PRE_OPERATIONAL));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_manager_set_target_state(f.mgr, 3, 0x42));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_manager_set_target_state(f.mgr, 0, CO_NMT_STOPPED));
	tb_advance(&f.bus, 2 * S);
	assert_network_runs(CO_NMT_STOPPED, CO_NMT_PRE_OPERATIONAL);
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 02"));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 03"));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 00"));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(f.mp->node));
}

/* A node that boots up while the network is stopped is stopped too and
 * not booted (no SDO in a stopped network); it is booted and started when
 * the network is started again. */
static void test_bootup_in_stopped_network(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_INT(
		0, co_manager_request_nmt(f.mgr, CO_MGR_ALL_NODES, CO_MGR_REQ_STOP, f.bus.now));
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	size_t reads = mf_sent(&f, 0x603, "40 00 10 00");
	co_nmt_local_cmd(f.bus.port[2].node, CO_NMT_CS_RESET_NODE, f.bus.now);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "02 03"));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL_UINT(reads, mf_sent(&f, 0x603, "40 00 10 00"));
	TEST_ASSERT_FALSE(co_manager_node_diag(f.mgr, 3)->booted);
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	/* the network starts again: node 3 is booted, then started */
	TEST_ASSERT_EQUAL_INT(
		0, co_manager_request_nmt(f.mgr, CO_MGR_ALL_NODES, CO_MGR_REQ_START, f.bus.now));
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(reads + 1, mf_sent(&f, 0x603, "40 00 10 00"));
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 3)->boot_count);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
}

/* A mandatory node booted meanwhile is waited for before the start. */
static void test_bootup_in_stopped_network_mandatory(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	co_manager_request_nmt(f.mgr, CO_MGR_ALL_NODES, CO_MGR_REQ_STOP, f.bus.now);
	tb_advance(&f.bus, 300 * MS);
	co_nmt_local_cmd(f.bus.port[1].node, CO_NMT_CS_RESET_NODE, f.bus.now);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_FALSE(co_manager_node_diag(f.mgr, 2)->booted);
	TEST_ASSERT_EQUAL_INT(
		0, co_manager_request_nmt(f.mgr, CO_MGR_ALL_NODES, CO_MGR_REQ_START, f.bus.now));
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 2)->boot_count);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* SDO requests of the manager (to any node) among the frames logged from
 * `from` on. */
static unsigned sdo_requests_since(size_t from)
{
	unsigned n = 0;
	for (size_t i = from; i < f.bus.log_len; i++)
		n += f.bus.log_from[i] == f.mp->idx && f.bus.log[i].id > 0x600 &&
		     f.bus.log[i].id < 0x680;
	return n;
}

/* Mandatory node 2 comes back after its loss with a boot-up. */
static void node2_reboots(void)
{
	f.bus.port[1].deliver = true;
	co_hb_producer_set(f.bus.port[1].node, 100, f.bus.now);
	co_nmt_local_cmd(f.bus.port[1].node, CO_NMT_CS_RESET_NODE, f.bus.now);
}

/* The error reaction stopped the network (1F80h bit 6): the lost mandatory
 * node that boots up again, and a silent optional node retried until then,
 * get no SDO request while the network is stopped (CiA 301 §7.3.2.2); the
 * application's start brings the network back although the mandatory node
 * has not booted yet: it is booted, then everything is started. */
static void test_stopped_network_no_sdo_then_application_start(void)
{
	line_2_3(MASTER | CO_MGR_1F80_STOP_ALL_ON_ERROR);
	mf_assign(&f, 4, SLAVE_BOOT, 0); /* absent: 1000h retried every second */
	lose_node2();
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	size_t mark = f.bus.log_len;
	node2_reboots();
	tb_advance(&f.bus, 5 * S);
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	TEST_ASSERT_EQUAL_UINT(0, sdo_requests_since(mark));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 1));
	TEST_ASSERT_FALSE(co_manager_node_diag(f.mgr, 2)->booted);
	/* way out: the application starts the network */
	unsigned reads2 = mf_sent(&f, 0x602, "40 00 10 00");
	TEST_ASSERT_EQUAL_INT(0, co_manager_start_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(reads2 + 1, mf_sent(&f, 0x602, "40 00 10 00"));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 2)->boot_count);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
	/* the silent optional node is looked for again */
	TEST_ASSERT_TRUE(mf_sent(&f, 0x604, "40 00 10 00") > 0);
}

/* With 1F80h bit 2 (the application starts the network) one start brings
 * the stopped network back too: it starts once node 2 has booted. */
static void test_stopped_network_application_start_without_self_start(void)
{
	line_2_3(MASTER | CO_MGR_1F80_NO_SELF_START | CO_MGR_1F80_STOP_ALL_ON_ERROR);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	TEST_ASSERT_EQUAL_INT(0, co_manager_start_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 100 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	node2_goes_silent();
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	size_t mark = f.bus.log_len;
	node2_reboots();
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_UINT(0, sdo_requests_since(mark));
	TEST_ASSERT_EQUAL_INT(0, co_manager_start_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));
}

/* Same stop; a boot asked for while the network is stopped (one node, or
 * 1F25h) waits too, and a new network boot is the other way out. */
static void test_stopped_network_no_sdo_then_network_boot(void)
{
	line_2_3(MASTER | CO_MGR_1F80_STOP_ALL_ON_ERROR);
	lose_node2();
	size_t mark = f.bus.log_len;
	node2_reboots();
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_node(f.mgr, 3, f.bus.now));
	TEST_ASSERT_EQUAL_HEX32(
		0, tb_od_write(&f.bus, f.mp->node, 0x1F25, 128, CO_MGR_CONF_SIGNATURE));
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL(CO_MGR_STOPPED, mstate());
	TEST_ASSERT_EQUAL_UINT(0, sdo_requests_since(mark));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 2));
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 3 * S);
	assert_network_runs(CO_NMT_OPERATIONAL, CO_NMT_OPERATIONAL);
}

/* 1F80h, 1F81h, 1F84h..1F89h are locked while the network boots; while
 * the line waits for a mandatory slave only 1F80h is (docs/config.md "The
 * manager"). */
static void test_boot_objects_locked_during_boot(void)
{
	co_manager_config c = { .sdo_timeout_ms = 100, .reset_wait_ms = 300 };
	line_2_3(MASTER);
	f.bus.port[2].deliver = false; /* node 3 deaf: the line waits for it */
	mf_assign(&f, 3, MANDATORY, 300);
	mf_start(&f, &c);
	tb_advance(&f.bus, 50 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTING, mstate());
	TEST_ASSERT_EQUAL_HEX32(0x08000022, tb_od_write(&f.bus, f.mp->node, 0x1F81, 3, SLAVE_BOOT));
	TEST_ASSERT_EQUAL_HEX32(0x08000022, tb_od_write(&f.bus, f.mp->node, 0x1F80, 0, MASTER));
	TEST_ASSERT_EQUAL_HEX32(0x08000022, tb_od_write(&f.bus, f.mp->node, 0x1F85, 2, 0));
	TEST_ASSERT_EQUAL_HEX32(0x08000022, tb_od_write(&f.bus, f.mp->node, 0x1F89, 0, 0));
	uint32_t v = 0;
	co_od_get_u32(f.mp->od, 0x1F81, 3, &v);
	TEST_ASSERT_EQUAL_HEX32(MANDATORY, v);
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL(CO_MGR_WAIT_MANDATORY, mstate());
	TEST_ASSERT_EQUAL_HEX32(0x08000022, tb_od_write(&f.bus, f.mp->node, 0x1F80, 0, MASTER));
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F85, 2, 0));
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F89, 0, 100));
	/* the new boot time ran out: booted, not started; writable again */
	tb_advance(&f.bus, 500 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, mstate());
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F81, 3, SLAVE_BOOT));
	/* the flying master (bit 5) is not supported */
	TEST_ASSERT_EQUAL_HEX32(0x06090030, tb_od_write(&f.bus, f.mp->node, 0x1F80, 0,
							MASTER | CO_MGR_1F80_FLYING_MASTER));
}

/* CiA 302-2's network list at run time: 1F81h:3 written in a running
 * network boots node 3 like a late node; withdrawn, node 3 is no longer
 * booted or reported (its heartbeats go on); node 2 is not disturbed. */
static void test_assignment_written_at_run_time(void)
{
	mf_init(&f, MASTER, 4);
	mf_slave(&f, 2, 100);
	mf_slave(&f, 3, 100);
	mf_assign(&f, 2, MANDATORY, 300);
	mf_expect(&f, 2, MF_DEVICE_TYPE, MF_VENDOR, MF_PRODUCT, MF_REVISION, 1002);
	mf_expect(&f, 3, MF_DEVICE_TYPE, MF_VENDOR, MF_PRODUCT, MF_REVISION, 1003);
	tb_advance(&f.bus, 10 * MS);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_FALSE(co_manager_node_diag(f.mgr, 3)->booted);

	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F81, 3, SLAVE_BOOT));
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_TRUE(co_manager_node_diag(f.mgr, 3)->booted);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, 3, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 2));

	unsigned events3 = mf_node_count(&f, 3, CO_MGR_NODE_UNEXPECTED) +
			   mf_node_count(&f, 3, CO_MGR_NODE_LOST);
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F81, 3, 0));
	tb_advance(&f.bus, 2 * S);
	co_mgr_diag d;
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_FALSE(co_mgr_bit(&d.assigned, 3));
	TEST_ASSERT_FALSE(co_mgr_bit(&d.booted, 3));
	TEST_ASSERT_EQUAL_UINT(events3, mf_node_count(&f, 3, CO_MGR_NODE_UNEXPECTED) +
						mf_node_count(&f, 3, CO_MGR_NODE_LOST));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_UINT(1, mf_boot_count(&f, 2, CO_MGR_STEP_START, 0));
	/* the manager's own node-ID and bad ones are refused */
	TEST_ASSERT_EQUAL_HEX32(0x06090030, tb_od_write(&f.bus, f.mp->node, 0x1F81,
							co_node_id(f.mp->node), SLAVE_BOOT));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_manager_node_reassigned(f.mgr, 0, f.bus.now));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_manager_node_reassigned(f.mgr, 128, f.bus.now));
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      co_manager_node_reassigned(f.mgr, co_node_id(f.mp->node), f.bus.now));
}

/* The manager's own NMT state is a flag of the line: a change of it alone
 * is reported as a state event (same state, new flags). */
static void test_state_event_on_flag_change(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_TRUE(co_manager_flags(f.mgr) & CO_MGR_F_MANAGER_OPERATIONAL);
	unsigned before = mf_count(&f, CO_EV_MGR_STATE);
	co_nmt_local_cmd(f.mp->node, CO_NMT_CS_ENTER_PREOP, f.bus.now);
	tb_advance(&f.bus, 10 * MS);
	TEST_ASSERT_EQUAL_UINT(before + 1, mf_count(&f, CO_EV_MGR_STATE));
	const co_event *last = NULL;
	for (unsigned i = 0; i < f.n_ev; i++)
		if (f.ev[i].kind == CO_EV_MGR_STATE)
			last = &f.ev[i];
	TEST_ASSERT_NOT_NULL(last);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, last->u.mgr.state);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, last->u.mgr.prev);
	TEST_ASSERT_FALSE(last->u.mgr.flags & CO_MGR_F_MANAGER_OPERATIONAL);
}

/* ---- 1F82h, 1F25h ----------------------------------------------------------------- */

static void test_1f82_request_nmt_over_od(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F82, 2, 4));
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, hb_of(f.bus.port + 1));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, co_manager_node_nmt_state(f.mgr, 2));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_manager_node_nmt_state(f.mgr, 3));
	TEST_ASSERT_EQUAL_HEX8(CO_MGR_NODE_UNKNOWN, co_manager_node_nmt_state(f.mgr, 50));
	TEST_ASSERT_EQUAL_HEX32(0x06090030, tb_od_write(&f.bus, f.mp->node, 0x1F82, 2, 9));
	/* all nodes: pre-operational */
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F82, 128, 127));
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_PREOP, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, hb_of(f.bus.port + 2));
	/* and start again */
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, f.mp->node, 0x1F82, 128, 5));
	tb_advance(&f.bus, 300 * MS);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, mstate());
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, hb_of(f.bus.port + 1));
}

static void test_1f25_configuration_request(void)
{
	line_2_3(MASTER);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	TEST_ASSERT_EQUAL_HEX32(0x08000020, tb_od_write(&f.bus, f.mp->node, 0x1F25, 3, 0x12345678));
	TEST_ASSERT_EQUAL_HEX32(0,
				tb_od_write(&f.bus, f.mp->node, 0x1F25, 3, CO_MGR_CONF_SIGNATURE));
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 3)->boot_count);
	TEST_ASSERT_EQUAL_UINT32(1, co_manager_node_diag(f.mgr, 2)->boot_count);
	TEST_ASSERT_EQUAL_HEX32(
		0, tb_od_write(&f.bus, f.mp->node, 0x1F25, 128, CO_MGR_CONF_SIGNATURE));
	tb_advance(&f.bus, 1 * S);
	TEST_ASSERT_EQUAL_UINT32(2, co_manager_node_diag(f.mgr, 2)->boot_count);
	TEST_ASSERT_EQUAL_UINT32(3, co_manager_node_diag(f.mgr, 3)->boot_count);
}

/* ---- diagnostics -------------------------------------------------------------------- */

static void test_diagnostics_bits_emcy_and_reset(void)
{
	line_2_3(MASTER);
	mf_assign(&f, 9, SLAVE_BOOT, 0);
	mf_start(&f, NULL);
	tb_advance(&f.bus, 2 * S);
	for (int i = 0; i < 10; i++)
		co_emcy_send(f.bus.port[1].node, (uint16_t)(0x1000 + i), 0x01, NULL, f.bus.now);
	tb_advance(&f.bus, 10 * MS);
	co_mgr_diag d;
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_TRUE(co_mgr_bit(&d.assigned, 2) && co_mgr_bit(&d.assigned, 3) &&
			 co_mgr_bit(&d.assigned, 9));
	TEST_ASSERT_FALSE(co_mgr_bit(&d.assigned, 4));
	TEST_ASSERT_TRUE(co_mgr_bit(&d.booted, 2) && co_mgr_bit(&d.booted, 3));
	TEST_ASSERT_FALSE(co_mgr_bit(&d.booted, 9));
	TEST_ASSERT_TRUE(co_mgr_bit(&d.operational, 2));
	TEST_ASSERT_TRUE(co_mgr_bit(&d.present, 3));
	TEST_ASSERT_FALSE(co_mgr_bit(&d.present, 9));
	TEST_ASSERT_TRUE(co_mgr_bit(&d.emcy_active, 2));
	TEST_ASSERT_FALSE(co_mgr_bit(&d.emcy_active, 3));
	const co_mgr_node_diag *nd = co_manager_node_diag(f.mgr, 2);
	TEST_ASSERT_EQUAL_UINT8(8, nd->emcy_count);
	/* the newest of the last 8 */
	TEST_ASSERT_EQUAL_HEX16(0x1009, nd->emcy[(nd->emcy_next + 7) % 8].code);
	TEST_ASSERT_EQUAL_HEX16(0x1002, nd->emcy[nd->emcy_next].code);
	TEST_ASSERT_EQUAL_UINT8(9, d.first_error_node); /* its B came first */
	TEST_ASSERT_EQUAL('B', d.first_error_status);
	co_manager_reset_counters(f.mgr);
	co_manager_get_diag(f.mgr, &d);
	TEST_ASSERT_EQUAL_UINT8(0, d.first_error_node);
	TEST_ASSERT_EQUAL_UINT8(0, co_manager_node_diag(f.mgr, 2)->emcy_count);
	TEST_ASSERT_EQUAL_UINT32(0, co_manager_node_diag(f.mgr, 2)->boot_count);
	TEST_ASSERT_TRUE(co_manager_node_diag(f.mgr, 2)->booted);
}

static void test_names(void)
{
	TEST_ASSERT_EQUAL_STRING("wait-mandatory", co_mgr_state_to_string(CO_MGR_WAIT_MANDATORY));
	TEST_ASSERT_EQUAL_STRING("?", co_mgr_state_to_string(CO_MGR_STATE_COUNT));
	TEST_ASSERT_EQUAL_STRING("vendor-id", co_mgr_step_to_string(CO_MGR_STEP_VENDOR));
	TEST_ASSERT_EQUAL_STRING("vendor-ID differs from 1F85h", co_mgr_status_to_string('D'));
	TEST_ASSERT_EQUAL_STRING("own-id", co_mgr_node_what_to_string(CO_MGR_NODE_OWN_ID));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_s44_two_nodes_boot_and_start);
	RUN_TEST(test_s45_device_type_mismatch_C);
	RUN_TEST(test_s46_zero_expected_not_read);
	RUN_TEST(test_s47_silent_mandatory_B_then_late);
	RUN_TEST(test_s48_configure_hook_then_start);
	RUN_TEST(test_s49_keep_alive_operational_not_reset_L);
	RUN_TEST(test_s50_bit2_waits_for_application);
	RUN_TEST(test_s51_bit6_stop_all);
	RUN_TEST(test_s51_bit4_reset_all);
	RUN_TEST(test_optional_loss_handled_alone_E);
	RUN_TEST(test_status_A_not_assigned);
	RUN_TEST(test_status_D_vendor);
	RUN_TEST(test_status_M_product);
	RUN_TEST(test_status_N_revision);
	RUN_TEST(test_status_O_serial);
	RUN_TEST(test_status_B_optional_retried);
	RUN_TEST(test_status_K_no_heartbeat);
	RUN_TEST(test_status_F_guarding);
	RUN_TEST(test_guarding_started);
	RUN_TEST(test_1f80_bit0_clear_plain_slave);
	RUN_TEST(test_1f80_bit1_one_broadcast);
	RUN_TEST(test_1f80_bit1_clear_one_by_one);
	RUN_TEST(test_1f80_bit3_application_starts_slaves);
	RUN_TEST(test_1f80_bits46_clear_node_alone);
	RUN_TEST(test_parallel_boot_bounded_by_pool);
	RUN_TEST(test_unexpected_node_reported_once);
	RUN_TEST(test_own_node_id_is_fatal);
	RUN_TEST(test_own_node_id_conflict_recovers_after_silence);
	RUN_TEST(test_own_id_emcy_and_sdo_answer_reported_boot_goes_on);
	RUN_TEST(test_own_id_guarding_request_and_malformed_heartbeat_not_fatal);
	RUN_TEST(test_nmt_to_manager_ignored_and_counted);
	RUN_TEST(test_nmt_to_manager_accepted_when_configured);
	RUN_TEST(test_rebooted_node_boots_again);
	RUN_TEST(test_duplicate_node_id);
	RUN_TEST(test_duplicate_node_id_two_sdo_answers);
	RUN_TEST(test_target_state_per_node);
	RUN_TEST(test_bootup_in_stopped_network);
	RUN_TEST(test_bootup_in_stopped_network_mandatory);
	RUN_TEST(test_stopped_network_no_sdo_then_application_start);
	RUN_TEST(test_stopped_network_application_start_without_self_start);
	RUN_TEST(test_stopped_network_no_sdo_then_network_boot);
	RUN_TEST(test_boot_objects_locked_during_boot);
	RUN_TEST(test_assignment_written_at_run_time);
	RUN_TEST(test_state_event_on_flag_change);
	RUN_TEST(test_scan_finds_missing_node);
	RUN_TEST(test_keep_op_restarts_node);
	RUN_TEST(test_1f82_request_nmt_over_od);
	RUN_TEST(test_1f25_configuration_request);
	RUN_TEST(test_diagnostics_bits_emcy_and_reset);
	RUN_TEST(test_names);
	return UNITY_END();
}
