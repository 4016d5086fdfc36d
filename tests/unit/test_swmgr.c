/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-3 software manager (core/swmgr.h) plugged into the CiA
 * 302-2 boot process (core/manager.h) as its "check software" step, with
 * a simulated slave on the in-memory bus whose program objects behave
 * like a device's: 1F50h:1 only takes an image into a cleared flash,
 * 1F51h:1 stops / clears / starts the program, a start refuses an image
 * whose trailer is not the 0x5A5A5A5A mark (or any image when the device
 * is told to refuse), and 1F56h:1 is the identification in the first 4
 * bytes of the running image.
 *
 * Paths: 1F56h:1 equals 1F55h:n (nothing downloaded), a 64 KiB update by
 * block transfer with progress (stop, clear, download, start, verify,
 * then the configure step and the start of the node), G (1F55h:n not
 * set; update needed without an image), H (update needed but 1F81h bit 6
 * clear), I (an image the device refuses; the started program reports
 * another identification), software not checked (bit 5 clear), and the
 * manual update of a running node.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/nmt.h"
#include "core/sdo.h"
#include "core/swmgr.h"
#include "tests/unit/support/mgr_fixture.h"
#include "unity.h"

#define MS 1000ull
#define S 1000000ull
#define NODE 2
#define MANDATORY (CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_MANDATORY)
#define IMAGE_SIZE 65536u
#define OLD_ID 0x01000001u
#define NEW_ID 0x02000007u
#define TRAILER 0x5A5A5A5Au

static mf f;
static co_swmgr_line line;
static co_swmgr_result last;
static unsigned results;
static tb_port *slave;
static uint8_t image[IMAGE_SIZE];
static uint32_t image_len;
static unsigned progress_calls;
static uint32_t progress_last, progress_total;

/* The simulated device's program, valued as its 1F51h:1 reads (CiA 302-3). */
enum {
	PROG_STOPPED = CO_SWMGR_PROG_STOPPED,
	PROG_RUNNING = CO_SWMGR_PROG_STARTED,
	PROG_CLEARED = CO_SWMGR_PROG_NONE
};
static uint8_t prog_state;
static bool refuse_all;
static unsigned commands[4];

static void ev_glue(void *ctx, const co_event *ev)
{
	(void)ctx;
	if (ev->kind == CO_EV_MGR_STATE || ev->kind == CO_EV_MGR_BOOT ||
	    ev->kind == CO_EV_MGR_NODE) {
		if (f.n_ev < MF_EVENTS)
			f.ev[f.n_ev++] = *ev;
		if (getenv("MF_TRACE"))
			fprintf(stderr, "%8.3f %s node %u step %s status %c abort %08x %04x:%u\n",
				(double)ev->now_us / 1e6, co_event_kind_to_string(ev->kind),
				ev->u.mgr.node, co_mgr_step_to_string(ev->u.mgr.step),
				ev->u.mgr.status ? ev->u.mgr.status : '-', ev->u.mgr.abort,
				ev->u.mgr.index, ev->u.mgr.sub);
		return;
	}
	if (f.mgr)
		co_manager_on_event(f.mgr, ev);
}

/* The software manager's outcome goes back to the boot process. */
static void sw_done(void *ctx, const co_swmgr_result *r, uint64_t now_us)
{
	uint16_t index;
	uint8_t sub;
	uint32_t value;
	(void)ctx;
	last = *r;
	results++;
	co_swmgr_result_finding(r, &index, &sub, &value);
	co_manager_software_done(f.mgr, r->node_id,
				 r->outcome == CO_SWMGR_FAILED_STATUS ? r->status : 0, r->abort,
				 index, sub, value, now_us);
}

static void sw_progress(void *ctx, uint8_t node_id, uint32_t sent, uint32_t total, uint64_t now_us)
{
	(void)ctx;
	(void)now_us;
	TEST_ASSERT_EQUAL_UINT8(NODE, node_id);
	if (progress_calls && sent <= progress_last)
		fprintf(stderr, "progress %u after %u\n", (unsigned)sent, (unsigned)progress_last);
	TEST_ASSERT_TRUE(sent > progress_last || progress_calls == 0);
	progress_calls++;
	progress_last = sent;
	progress_total = total;
}

static uint32_t src_size(void *ctx, uint8_t node_id)
{
	(void)ctx;
	return node_id == NODE ? image_len : 0;
}

static int src_read(void *ctx, uint8_t node_id, uint32_t offset, uint8_t *buf, uint32_t len)
{
	(void)ctx;
	if (node_id != NODE || offset > image_len)
		return -EINVAL;
	if (len > image_len - offset)
		len = image_len - offset;
	memcpy(buf, image + offset, len);
	return (int)len;
}

static uint32_t get_le32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_le32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}

/* The identification survives the resets of the boot (it is the
 * program's, not a parameter). */
static void set_id(uint32_t id)
{
	co_od_entry *e = co_od_find(slave->od, 0x1F56, 1);
	co_od_entry_set_raw(e, id);
	co_od_entry_set_default_raw(e, id);
}

/* The device's program (the flash: it survives resets). */
static void set_program(uint8_t state)
{
	co_od_entry *e = co_od_find(slave->od, 0x1F51, 1);
	prog_state = state;
	co_od_entry_set_raw(e, state);
	co_od_entry_set_default_raw(e, state);
}

static uint32_t data_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	(void)a;
	return prog_state == PROG_CLEARED ? 0 : 0x08000022u;
}

static void data_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	(void)a;
	set_program(PROG_STOPPED);
}

static uint32_t control_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_od_entry *d = co_od_find(slave->od, 0x1F50, 1);
	(void)ctx;
	(void)e;
	if (!a->data || a->size != 1 || a->data[0] > 3)
		return 0x06090030u;
	commands[a->data[0]]++;
	switch (a->data[0]) {
	case CO_SWMGR_CTL_STOP:
		if (prog_state == PROG_RUNNING)
			prog_state = PROG_STOPPED;
		return 0;
	case CO_SWMGR_CTL_CLEAR:
		if (prog_state == PROG_RUNNING)
			return 0x08000022u;
		co_od_set_bytes(slave->od, 0x1F50, 1, "", 0);
		set_id(0);
		prog_state = PROG_CLEARED;
		return 0;
	case CO_SWMGR_CTL_START:
		if (prog_state == PROG_CLEARED)
			return 0x08000022u;
		if (refuse_all || d->size < 8 || get_le32(d->data + d->size - 4) != TRAILER)
			return 0x08000020u;
		set_id(get_le32(d->data));
		prog_state = PROG_RUNNING;
		return 0;
	default:
		return 0;
	}
}

/* The write stores the command; a read gives the program's state. */
static void control_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	(void)a;
	set_program(prog_state);
}

static const co_od_hooks data_hooks = { .check_write = data_check, .after_write = data_written };
static const co_od_hooks control_hooks = { .check_write = control_check,
					   .after_write = control_written };

/* An image whose first 4 bytes are its identification and whose last 4
 * are the trailer the device checks (or not, with `bad`). */
static void make_image(uint32_t id, bool bad)
{
	image_len = IMAGE_SIZE;
	for (uint32_t i = 0; i < image_len; i++)
		image[i] = (uint8_t)(i * 7 + (i >> 8));
	put_le32(image, id);
	put_le32(image + image_len - 4, bad ? 0x12345678u : TRAILER);
}

void setUp(void)
{
	co_od_desc d = { .index = 0x1F50,
			 .sub = 1,
			 .obj_code = CO_OBJ_ARRAY,
			 .type = CO_T_DOMAIN,
			 .access = CO_ACC_RW,
			 .max_size = IMAGE_SIZE + 1024,
			 .name = "ProgramData" };
	co_swmgr_source src = { .size = src_size, .read = src_read };

	memset(&last, 0, sizeof last);
	memset(commands, 0, sizeof commands);
	results = progress_calls = 0;
	progress_last = progress_total = 0;
	refuse_all = false;
	image_len = 0;
	mf_init(&f, CO_MGR_1F80_MASTER, 4);
	slave = mf_slave(&f, NODE, 100);
	/* the slave's program objects, running its old program */
	TEST_ASSERT_EQUAL_INT(0, co_od_ensure_num(slave->od, 0x1F50, 0, CO_T_UNSIGNED8, CO_ACC_RO,
						  1, CO_OBJ_ARRAY));
	TEST_ASSERT_EQUAL_INT(0, co_od_add(slave->od, &d, NULL));
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_add_array(slave->od, 0x1F51, CO_T_UNSIGNED8, 1, CO_ACC_RW, 0));
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_add_array(slave->od, 0x1F56, CO_T_UNSIGNED32, 1, CO_ACC_RO, 0));
	TEST_ASSERT_EQUAL_INT(0, co_od_set_hooks(slave->od, 0x1F50, 1, &data_hooks, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_set_hooks(slave->od, 0x1F51, 1, &control_hooks, NULL));
	set_id(OLD_ID);
	set_program(PROG_RUNNING);

	mf_assign(&f, NODE, MANDATORY | CO_SWMGR_F81_CHECK | CO_SWMGR_F81_UPDATE, 300);
	mf_expect(&f, NODE, MF_DEVICE_TYPE, MF_VENDOR, MF_PRODUCT, MF_REVISION, 1000u + NODE);
	co_od_set_u32(f.mp->od, 0x1F89, 0, 10000);
	TEST_ASSERT_EQUAL_INT(0, co_od_add_swmgr_defaults(f.mp->od));
	co_od_set_u32(f.mp->od, CO_SWMGR_IDX_EXPECTED, NODE, NEW_ID);
	co_swmgr_line_init(&line, f.mp->node, &src, sw_done, NULL);
	line.progress = sw_progress;
	line.progress_ctx = NULL;
	f.mp->ext_event = ev_glue;
	tb_advance(&f.bus, 10 * MS);
}

void tearDown(void)
{
	co_swmgr_line_cancel_all(&line, f.bus.now);
	mf_fini(&f);
}

static void boot(void)
{
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 200,
					   .software = co_swmgr_line_check,
					   .software_ctx = &line });
	tb_advance(&f.bus, 4 * S);
}

static uint32_t slave_id(void)
{
	uint32_t v = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u32(slave->od, 0x1F56, 1, &v));
	return v;
}

static void assert_not_started(void)
{
	TEST_ASSERT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_CONFIGURE, 0));
	TEST_ASSERT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_NOT_EQUAL(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));
}

static void test_matching_software_is_left_alone(void)
{
	co_od_set_u32(f.mp->od, CO_SWMGR_IDX_EXPECTED, NODE, OLD_ID);
	make_image(NEW_ID, false);
	boot();
	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_UNCHANGED, last.outcome);
	TEST_ASSERT_EQUAL_HEX32(OLD_ID, last.found);
	TEST_ASSERT_FALSE(last.downloaded);
	TEST_ASSERT_EQUAL_UINT(0, commands[CO_SWMGR_CTL_STOP] + commands[CO_SWMGR_CTL_CLEAR]);
	TEST_ASSERT_EQUAL_UINT(0, progress_calls);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 0));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));
}

static void test_update_64k_by_block_transfer_then_verified_and_started(void)
{
	const co_od_entry *e;

	make_image(NEW_ID, false);
	boot();
	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_UPDATED, last.outcome);
	TEST_ASSERT_EQUAL_HEX32(NEW_ID, last.found);
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, last.bytes);
	TEST_ASSERT_EQUAL_STRING("block", sdo_mode_to_string(last.mode));
	/* stop, clear, start once each, in that order (the device checks) */
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_STOP]);
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_CLEAR]);
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_START]);
	TEST_ASSERT_EQUAL_UINT8(PROG_RUNNING, prog_state);
	/* the flash holds the image byte for byte */
	e = co_od_find(slave->od, 0x1F50, 1);
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, e->size);
	TEST_ASSERT_EQUAL_MEMORY(image, e->data, IMAGE_SIZE);
	TEST_ASSERT_EQUAL_HEX32(NEW_ID, slave_id());
	/* block transfer: block download initiate (ccs 6) on 602h */
	TEST_ASSERT_TRUE(mf_sent(&f, 0x602, "C6 50 1F 01") + mf_sent(&f, 0x602, "C2 50 1F 01") >=
			 1);
	/* progress every 4 KiB and at the end */
	TEST_ASSERT_EQUAL_UINT(IMAGE_SIZE / CO_SWMGR_PROGRESS_STEP, progress_calls);
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, progress_last);
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, progress_total);
	/* then the rest of the boot: the node is started */
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 0));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));

	/* next boot: 1F56h:1 matches now, nothing downloaded */
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 4 * S);
	TEST_ASSERT_EQUAL_UINT(2, results);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_UNCHANGED, last.outcome);
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_CLEAR]);
}

static void test_g_when_1f55h_is_not_configured(void)
{
	co_od_set_u32(f.mp->od, CO_SWMGR_IDX_EXPECTED, NODE, 0);
	make_image(NEW_ID, false);
	boot();
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 'G');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1F55, e->index);
	TEST_ASSERT_EQUAL_UINT8(NODE, e->sub);
	TEST_ASSERT_EQUAL_UINT(0, results); /* decided before any request */
	TEST_ASSERT_EQUAL_HEX32(OLD_ID, slave_id());
	assert_not_started();
}

static void test_g_when_an_update_is_needed_without_an_image(void)
{
	boot(); /* image_len 0 */
	TEST_ASSERT_TRUE(results >= 1);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_FAILED_STATUS, last.outcome);
	TEST_ASSERT_EQUAL_INT('G', last.status);
	TEST_ASSERT_EQUAL_HEX16(CO_SWMGR_IDX_IMAGE, last.index);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 'G'));
	TEST_ASSERT_EQUAL_UINT(0, commands[CO_SWMGR_CTL_STOP]);
	TEST_ASSERT_EQUAL_UINT8(PROG_RUNNING, prog_state);
	assert_not_started();
}

static void test_h_when_the_update_is_not_allowed(void)
{
	mf_assign(&f, NODE, MANDATORY | CO_SWMGR_F81_CHECK, 300);
	make_image(NEW_ID, false);
	boot();
	TEST_ASSERT_TRUE(results >= 1);
	TEST_ASSERT_EQUAL_INT('H', last.status);
	TEST_ASSERT_EQUAL_HEX32(OLD_ID, last.found);
	TEST_ASSERT_EQUAL_HEX32(NEW_ID, last.expected);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 'H'));
	TEST_ASSERT_EQUAL_UINT(0, commands[CO_SWMGR_CTL_STOP] + commands[CO_SWMGR_CTL_CLEAR]);
	TEST_ASSERT_EQUAL_HEX32(OLD_ID, slave_id());
	assert_not_started();
}

static void test_i_when_the_device_refuses_the_image(void)
{
	make_image(NEW_ID, true);
	boot();
	TEST_ASSERT_TRUE(results >= 1);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_FAILED_STATUS, last.outcome);
	TEST_ASSERT_EQUAL_INT('I', last.status);
	TEST_ASSERT_EQUAL_HEX16(0x1F51, last.index);
	TEST_ASSERT_EQUAL_UINT8(1, last.sub);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_START, last.step); /* refused on the start */
	TEST_ASSERT_EQUAL_HEX32(0x08000020, last.abort);
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, last.bytes);
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 'I');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1F51, e->index);
	TEST_ASSERT_EQUAL_HEX32(0x08000020, e->abort);
	TEST_ASSERT_EQUAL_UINT8(PROG_STOPPED, prog_state);
	assert_not_started();
}

static void test_i_when_the_started_program_is_not_the_expected_one(void)
{
	make_image(0x0BADBEEFu, false);
	boot();
	TEST_ASSERT_TRUE(results >= 1);
	TEST_ASSERT_EQUAL_INT('I', last.status);
	TEST_ASSERT_EQUAL_HEX16(0x1F56, last.index);
	TEST_ASSERT_EQUAL_HEX32(0, last.abort);
	TEST_ASSERT_EQUAL_HEX32(0x0BADBEEFu, last.found);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 'I'));
	assert_not_started();
}

/* Without bit 5 the software is not checked, but the program state is
 * read (a look-only job): a running program, nothing more to say. */
static void test_software_not_checked_without_bit_5(void)
{
	mf_assign(&f, NODE, MANDATORY | CO_SWMGR_F81_UPDATE, 300);
	make_image(NEW_ID, false);
	boot();
	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_TRUE(last.look_only);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_UNCHANGED, last.outcome);
	TEST_ASSERT_EQUAL_UINT8(PROG_RUNNING, last.program);
	TEST_ASSERT_FALSE(co_swmgr_program_down(&last));
	TEST_ASSERT_EQUAL_UINT(0, commands[CO_SWMGR_CTL_STOP]);
	TEST_ASSERT_EQUAL_HEX32(OLD_ID, slave_id());
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
}

/* A program download cut short (the manager restarted between the clear
 * and the start) left the flash cleared; no software_id is configured
 * (bit 5 clear). The boot reads 1F51h:1 and names it in the check
 * software event (1F51h:01 = 3), which the owner reports; with the
 * software unchecked the boot goes on as 1F81h says. */
static void test_cut_download_seen_without_software_id(void)
{
	const co_ev_mgr *e;
	mf_assign(&f, NODE, MANDATORY, 300);
	set_program(PROG_CLEARED);
	set_id(0);
	boot();
	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_TRUE(last.look_only);
	TEST_ASSERT_EQUAL_UINT8(CO_SWMGR_PROG_NONE, last.program);
	TEST_ASSERT_TRUE(co_swmgr_program_down(&last));
	TEST_ASSERT_EQUAL_STRING("no program", co_swmgr_program_to_string(last.program));
	e = mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1F51, e->index);
	TEST_ASSERT_EQUAL_UINT8(1, e->sub);
	TEST_ASSERT_EQUAL_UINT32(CO_SWMGR_PROG_NONE, e->value);
	TEST_ASSERT_EQUAL_UINT(0, commands[CO_SWMGR_CTL_START]); /* nothing written */
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
}

/* With bit 5 a program that does not run is updated even though 1F56h:1
 * still names the expected software (the boot loader keeps the old
 * identification); without update permission: H on 1F51h:1. */
static void test_program_not_running_updated_although_1f56h_matches(void)
{
	co_od_set_u32(f.mp->od, CO_SWMGR_IDX_EXPECTED, NODE, OLD_ID);
	make_image(OLD_ID, false);
	set_program(PROG_STOPPED);
	boot();
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_UPDATED, last.outcome);
	TEST_ASSERT_EQUAL_UINT8(CO_SWMGR_PROG_STOPPED, last.program);
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_CLEAR]);
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_START]);
	TEST_ASSERT_EQUAL_UINT8(PROG_RUNNING, prog_state);
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
}

static void test_h_on_1f51h_when_a_stopped_program_may_not_be_updated(void)
{
	const co_ev_mgr *e;
	mf_assign(&f, NODE, MANDATORY | CO_SWMGR_F81_CHECK, 300);
	co_od_set_u32(f.mp->od, CO_SWMGR_IDX_EXPECTED, NODE, OLD_ID);
	set_program(PROG_CLEARED);
	boot();
	TEST_ASSERT_EQUAL_INT('H', last.status);
	TEST_ASSERT_EQUAL_HEX16(0x1F51, last.index);
	e = mf_boot(&f, NODE, CO_MGR_STEP_SOFTWARE, 'H');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x1F51, e->index);
	TEST_ASSERT_EQUAL_UINT32(CO_SWMGR_PROG_NONE, e->value);
	assert_not_started();
}

static void test_manual_update_of_a_running_node(void)
{
	co_swmgr_line manual;
	co_swmgr_source src = { .size = src_size, .read = src_read };

	mf_assign(&f, NODE, MANDATORY, 300);
	boot();
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));
	co_swmgr_line_init(&manual, f.mp->node, &src, NULL, NULL);
	manual.progress = sw_progress;
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_swmgr_line_program(&manual, NODE, NULL, 0, f.bus.now));
	make_image(NEW_ID, false);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_swmgr_line_program(&manual, 0, NULL, 0, f.bus.now));
	TEST_ASSERT_EQUAL_INT(0, co_swmgr_line_program(&manual, NODE, NULL, 0, f.bus.now));
	TEST_ASSERT_EQUAL_INT(-EBUSY, co_swmgr_line_program(&manual, NODE, NULL, 0, f.bus.now));
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_FALSE(co_swmgr_running(&manual.job[NODE - 1]));
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_UPDATED, manual.job[NODE - 1].res.outcome);
	TEST_ASSERT_EQUAL_HEX32(NEW_ID, slave_id());
	TEST_ASSERT_EQUAL_UINT(1, commands[CO_SWMGR_CTL_STOP]); /* stopped first */
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, progress_last);

	/* an image given with the request (the mailbox's MGR_PROGRAM) and an
	 * expected identification the new program does not report: I at the
	 * verify, the program itself was sent and started */
	progress_calls = 0;
	progress_last = 0;
	TEST_ASSERT_EQUAL_INT(0,
			      co_swmgr_line_program(&manual, NODE, &src, 0x12345678u, f.bus.now));
	tb_advance(&f.bus, 3 * S);
	const co_swmgr_result *r = &manual.job[NODE - 1].res;
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_FAILED_STATUS, r->outcome);
	TEST_ASSERT_EQUAL_INT('I', r->status);
	TEST_ASSERT_EQUAL_INT(CO_SWMGR_VERIFY, r->step);
	TEST_ASSERT_EQUAL_HEX16(0x1F56, r->index);
	TEST_ASSERT_EQUAL_HEX32(0x12345678u, r->expected);
	TEST_ASSERT_EQUAL_HEX32(NEW_ID, r->found);
	TEST_ASSERT_EQUAL_UINT32(IMAGE_SIZE, r->bytes);
	co_swmgr_line_cancel_all(&manual, f.bus.now);
}

static void test_names(void)
{
	TEST_ASSERT_EQUAL_STRING("download", co_swmgr_state_to_string(CO_SWMGR_DOWNLOAD));
	TEST_ASSERT_EQUAL_STRING("updated", co_swmgr_outcome_to_string(CO_SWMGR_UPDATED));
	TEST_ASSERT_EQUAL_STRING("software", co_mgr_step_to_string(CO_MGR_STEP_SOFTWARE));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_manager_software_done(NULL, 0, 0, 0, 0, 0, 0, 0));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_matching_software_is_left_alone);
	RUN_TEST(test_update_64k_by_block_transfer_then_verified_and_started);
	RUN_TEST(test_g_when_1f55h_is_not_configured);
	RUN_TEST(test_g_when_an_update_is_needed_without_an_image);
	RUN_TEST(test_h_when_the_update_is_not_allowed);
	RUN_TEST(test_i_when_the_device_refuses_the_image);
	RUN_TEST(test_i_when_the_started_program_is_not_the_expected_one);
	RUN_TEST(test_software_not_checked_without_bit_5);
	RUN_TEST(test_cut_download_seen_without_software_id);
	RUN_TEST(test_program_not_running_updated_although_1f56h_matches);
	RUN_TEST(test_h_on_1f51h_when_a_stopped_program_may_not_be_updated);
	RUN_TEST(test_manual_update_of_a_running_node);
	RUN_TEST(test_names);
	return UNITY_END();
}
