/* SPDX-License-Identifier: MIT */
/*
 * core/manager_od.c - the manager's objects: Request NMT (1F82h),
 * configuration request (1F25h), the lock of 1F80h..1F89h during the
 * boot, and their defaults.
 */
#include "core/manager_int.h"
#include "core/heartbeat.h"
#include "core/nmt.h"

static uint32_t f82_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	int rc;
	if (a->origin == CO_OD_ORIGIN_RESET)
		return 0;
	if (!a->data || a->size != 1)
		return SDO_AB_TYPE_LEN;
	if (mgr_cmd_to_cs(a->data[0]) < 0)
		return SDO_AB_VALUE;
	rc = co_manager_request_nmt(m, e->sub, a->data[0], m->node->now_us);
	return sdo_abort_of_errno(rc);
}

static uint32_t f82_read(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	(void)a;
	co_od_entry_set_raw(e, e->sub <= 127 ? co_manager_node_nmt_state(m, e->sub) : 0);
	return 0;
}

static const co_od_hooks f82_hooks = { .check_write = f82_check, .read = f82_read };

static uint32_t f25_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	uint32_t sig;
	uint64_t now = m->node->now_us;
	if (a->origin == CO_OD_ORIGIN_RESET)
		return 0;
	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	sig = (uint32_t)a->data[0] | (uint32_t)a->data[1] << 8 | (uint32_t)a->data[2] << 16 |
	      (uint32_t)a->data[3] << 24;
	if (sig != CO_MGR_CONF_SIGNATURE)
		return SDO_AB_STORE;
	if (!mgr_active(m))
		return SDO_AB_DEV_STATE;
	if (e->sub == CO_MGR_ALL_NODES) {
		mgr_enter(m, now);
		for (unsigned id = 1; id <= 127; id++)
			if (is_slave(m, (uint8_t)id) && !bs_running(&m->s[id])) {
				m->s[id].d.booted = false;
				mgr_boot_begin(&m->s[id], false, false, now);
			}
		m->check_pending = true;
		mgr_after(m, now);
		return 0;
	}
	if (bs_running(&m->s[e->sub]))
		return SDO_AB_DEV_STATE;
	return co_manager_boot_node(m, e->sub, now) < 0 ? SDO_AB_DEV_STATE : 0;
}

static const co_od_hooks f25_hooks = { .check_write = f25_check };

/* 1F80h, 1F81h, 1F84h..1F89h while the network boots: the boot reads
 * them step by step, a change in the middle would boot a node against
 * half old, half new values. Once its first pass is over and the line
 * waits for mandatory slaves, each node's boot slave process reads its
 * objects when it (re)starts, as in a running network: 1F81h and
 * 1F84h..1F88h may be written then (a node added or removed while a
 * mandatory one is missing; a 1F81h:n write restarts node n's process),
 * and 1F89h (a new limit, 0 = wait for ever); 1F80h stays locked. The
 * flying master (1F80h bit 5) is not supported. Writes are refused with
 * 08000022h (device state) or 06090030h (value range); docs/config.md
 * "The manager" describes the lock. */
static uint32_t lock_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	if (a->origin == CO_OD_ORIGIN_RESET)
		return 0;
	if (e->index == 0x1F80 && a->data && a->size >= 1 &&
	    (a->data[0] & CO_MGR_1F80_FLYING_MASTER))
		return SDO_AB_VALUE;
	/* the manager is no slave of its own network */
	if (e->index == 0x1F81 && e->sub == m->own_id && a->data && a->size >= 1 &&
	    (a->data[0] & CO_MGR_1F81_SLAVE))
		return SDO_AB_VALUE;
	if (st == CO_MGR_RESETTING || st == CO_MGR_BOOTING)
		return SDO_AB_DEV_STATE;
	if (st == CO_MGR_WAIT_MANDATORY && e->index == 0x1F80)
		return SDO_AB_DEV_STATE;
	return 0;
}

static const co_od_hooks lock_hooks = { .check_write = lock_check };

/* 1F81h:n written after the network boot: the node follows at once. */
static void assignment_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	if (a->origin == CO_OD_ORIGIN_RESET)
		return;
	(void)co_manager_node_reassigned(m, e->sub, m->node->now_us);
}

static const co_od_hooks assignment_hooks = { .check_write = lock_check,
					      .after_write = assignment_written };

/* 1F89h written while the line waits for mandatory slaves: the new boot
 * time counts from the start of the boot (0 = wait for ever); one that
 * has passed ends the wait at the next tick. */
static void boot_time_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	co_manager *m = ctx;
	uint32_t bt = od_u32(m, 0x1F89, 0);
	(void)e;
	(void)a;
	if (co_fsm_state_of(&m->fsm) != CO_MGR_WAIT_MANDATORY)
		return;
	m->timer_us = bt ? m->boot_started_us + (uint64_t)bt * 1000u : CO_NO_DEADLINE;
}

static const co_od_hooks boot_time_hooks = { .check_write = lock_check,
					     .after_write = boot_time_written };

/* The objects lock_check guards (sub-index ranges). */
static const struct locked_object {
	uint16_t index;
	uint8_t first, last;
} locked_objects[] = {
	{ 0x1F80, 0, 0 },   { 0x1F81, 1, 127 }, { 0x1F84, 1, 127 }, { 0x1F85, 1, 127 },
	{ 0x1F86, 1, 127 }, { 0x1F87, 1, 127 }, { 0x1F88, 1, 127 }, { 0x1F89, 0, 0 },
};

static const co_od_hooks *hooks_of(uint16_t index)
{
	return index == 0x1F89   ? &boot_time_hooks
	       : index == 0x1F81 ? &assignment_hooks
				 : &lock_hooks;
}

static void set_lock_hooks(co_manager *m, bool on)
{
	for (size_t i = 0; i < sizeof(locked_objects) / sizeof(locked_objects[0]); i++)
		for (unsigned sub = locked_objects[i].first; sub <= locked_objects[i].last; sub++)
			(void)co_od_set_hooks(m->od, locked_objects[i].index, (uint8_t)sub,
					      !on ? NULL : hooks_of(locked_objects[i].index),
					      on ? m : NULL);
}

void mgr_od_hooks(co_manager *m, bool on)
{
	for (unsigned sub = 1; sub <= 128; sub++) {
		(void)co_od_set_hooks(m->od, 0x1F82, (uint8_t)sub, on ? &f82_hooks : NULL,
				      on ? m : NULL);
		(void)co_od_set_hooks(m->od, 0x1F25, (uint8_t)sub, on ? &f25_hooks : NULL,
				      on ? m : NULL);
	}
	set_lock_hooks(m, on);
}

int co_od_add_manager_defaults(co_od *od, uint32_t f80_def)
{
	int rc;
	if ((rc = co_od_ensure_num(od, 0x1F80, 0, CO_T_UNSIGNED32, CO_ACC_RW | CO_ACC_PERSIST,
				   f80_def, 0)) < 0)
		return rc;
	if ((rc = co_od_ensure_num(od, 0x1F89, 0, CO_T_UNSIGNED32, CO_ACC_RW | CO_ACC_PERSIST, 0,
				   0)) < 0)
		return rc;
	static const uint16_t arrays[] = { 0x1F81, 0x1F84, 0x1F85, 0x1F86, 0x1F87, 0x1F88 };
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); i++)
		if (!co_od_has_index(od, arrays[i]) &&
		    (rc = co_od_add_array(od, arrays[i], CO_T_UNSIGNED32, 127,
					  CO_ACC_RW | CO_ACC_PERSIST, 0)) < 0)
			return rc;
	if (!co_od_has_index(od, 0x1F82) &&
	    (rc = co_od_add_array(od, 0x1F82, CO_T_UNSIGNED8, 128, CO_ACC_RW, 0)) < 0)
		return rc;
	if (!co_od_has_index(od, 0x1F25) &&
	    (rc = co_od_add_array(od, 0x1F25, CO_T_UNSIGNED32, 128, CO_ACC_WO, 0)) < 0)
		return rc;
	if ((rc = co_od_add_comm_defaults_nmt(od, 1)) < 0)
		return rc;
	return co_od_add_comm_defaults_hb(od, 127, 0);
}
