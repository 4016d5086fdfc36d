/* SPDX-License-Identifier: MIT */
#include "tests/unit/support/mgr_fixture.h"

#include <assert.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/emcy.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/nmt.h"

static void mf_event(void *ctx, const co_event *ev)
{
	mf *f = ctx;
	if (ev->kind == CO_EV_MGR_STATE || ev->kind == CO_EV_MGR_BOOT ||
	    ev->kind == CO_EV_MGR_NODE) {
		if (f->n_ev < MF_EVENTS)
			f->ev[f->n_ev++] = *ev;
		if (getenv("MF_TRACE"))
			fprintf(stderr,
				"%8.3f %s node %u state %s step %s status %c what %s abort %08x "
				"%04x:%u v %x\n",
				(double)ev->now_us / 1e6, co_event_kind_to_string(ev->kind),
				ev->u.mgr.node, co_mgr_state_to_string(ev->u.mgr.state),
				co_mgr_step_to_string(ev->u.mgr.step),
				ev->u.mgr.status ? ev->u.mgr.status : '-',
				co_mgr_node_what_to_string(ev->u.mgr.what), ev->u.mgr.abort,
				ev->u.mgr.index, ev->u.mgr.sub, ev->u.mgr.value);
		return;
	}
	if (f->mgr)
		co_manager_on_event(f->mgr, ev);
}

static uint64_t mf_tick(void *ctx, uint64_t now)
{
	mf *f = ctx;
	return f->mgr ? co_manager_tick(f->mgr, now) : CO_NO_DEADLINE;
}

static uint64_t mf_deadline(void *ctx)
{
	mf *f = ctx;
	return f->mgr ? co_manager_next_deadline_us(f->mgr) : CO_NO_DEADLINE;
}

void mf_init(mf *f, uint32_t f80, uint8_t n_channels)
{
	co_od *od = NULL;
	co_node_config cfg = { 0 };

	memset(f, 0, sizeof(*f));
	tb_init(&f->bus);
	assert(co_od_create(&od, 256) == 0);
	assert(co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, 0x12D, NULL) == 0);
	assert(co_od_add_comm_defaults_emcy(od, MF_MANAGER_ID, 8, 127, 1) == 0);
	assert(co_od_add_comm_defaults_guard(od) == 0);
	assert(co_od_add_manager_defaults(od, f80) == 0);
	/* the manager keeps its PDOs running when a slave is lost */
	assert(co_od_set_u8(od, 0x1029, 1, 1) == 0);
	cfg.node_id = MF_MANAGER_ID;
	cfg.sdo_client_count = n_channels;
	f->mp = tb_add_node(&f->bus, &cfg, od);
	assert(f->mp);
	f->mp->ext_event = mf_event;
	f->mp->ext_tick = mf_tick;
	f->mp->ext_deadline = mf_deadline;
	f->mp->ext_ctx = f;
}

void mf_fini(mf *f)
{
	co_manager_destroy(f->mgr);
	f->mgr = NULL;
	tb_fini(&f->bus);
}

tb_port *mf_slave_ex(mf *f, uint8_t id, uint16_t hb_ms, uint32_t device_type, uint32_t vendor)
{
	co_od *od = NULL;
	co_node_config cfg = { 0 };
	tb_port *p;

	assert(co_od_create(&od, 64) == 0);
	assert(co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, device_type, NULL) == 0);
	assert(co_od_add_num(od, 0x1018, 0, CO_T_UNSIGNED8, CO_ACC_RO, 4, NULL) == 0);
	assert(co_od_add_num(od, 0x1018, 1, CO_T_UNSIGNED32, CO_ACC_RO, vendor, NULL) == 0);
	assert(co_od_add_num(od, 0x1018, 2, CO_T_UNSIGNED32, CO_ACC_RO, MF_PRODUCT, NULL) == 0);
	assert(co_od_add_num(od, 0x1018, 3, CO_T_UNSIGNED32, CO_ACC_RO, MF_REVISION, NULL) == 0);
	assert(co_od_add_num(od, 0x1018, 4, CO_T_UNSIGNED32, CO_ACC_RO, 1000u + id, NULL) == 0);
	assert(co_od_add_comm_defaults_emcy(od, id, 8, 0, 0) == 0);
	assert(co_od_add_comm_defaults_hb(od, 0, hb_ms) == 0);
	assert(co_od_add_comm_defaults_nmt(od, 1) == 0);
	assert(co_od_add_comm_defaults_guard(od) == 0);
	cfg.node_id = id;
	p = tb_add_node(&f->bus, &cfg, od);
	assert(p);
	return p;
}

tb_port *mf_slave(mf *f, uint8_t id, uint16_t hb_ms)
{
	return mf_slave_ex(f, id, hb_ms, MF_DEVICE_TYPE, MF_VENDOR);
}

void mf_assign(mf *f, uint8_t id, uint32_t f81, uint16_t hb_ms)
{
	co_od *od = f->mp->od;
	assert(co_od_set_u32(od, 0x1F81, id, f81) == 0);
	/* through the hooks, so that the heartbeat consumer takes it */
	if (hb_ms)
		assert(tb_od_write(&f->bus, f->mp->node, 0x1016, id, (uint32_t)id << 16 | hb_ms) ==
		       0);
}

void mf_expect(mf *f, uint8_t id, uint32_t device_type, uint32_t vendor, uint32_t product,
	       uint32_t revision, uint32_t serial)
{
	co_od *od = f->mp->od;
	assert(co_od_set_u32(od, 0x1F84, id, device_type) == 0);
	assert(co_od_set_u32(od, 0x1F85, id, vendor) == 0);
	assert(co_od_set_u32(od, 0x1F86, id, product) == 0);
	assert(co_od_set_u32(od, 0x1F87, id, revision) == 0);
	assert(co_od_set_u32(od, 0x1F88, id, serial) == 0);
}

void mf_start(mf *f, const co_manager_config *cfg)
{
	co_manager_config def = { .sdo_timeout_ms = 100, .reset_wait_ms = 500, .retry_ms = 1000 };
	assert(co_manager_create(&f->mgr, f->mp->node, cfg ? cfg : &def) == 0);
}

unsigned mf_count(const mf *f, co_event_kind kind)
{
	unsigned n = 0;
	for (unsigned i = 0; i < f->n_ev; i++)
		n += f->ev[i].kind == kind;
	return n;
}

static bool boot_match(const co_event *e, uint8_t node, int step, int status)
{
	return e->kind == CO_EV_MGR_BOOT && e->u.mgr.node == node &&
	       (step < 0 || e->u.mgr.step == step) && (status < 0 || e->u.mgr.status == status);
}

const co_ev_mgr *mf_boot(const mf *f, uint8_t node, int step, int status)
{
	for (unsigned i = f->n_ev; i-- > 0;)
		if (boot_match(&f->ev[i], node, step, status))
			return &f->ev[i].u.mgr;
	return NULL;
}

unsigned mf_boot_count(const mf *f, uint8_t node, int step, int status)
{
	unsigned n = 0;
	for (unsigned i = 0; i < f->n_ev; i++)
		n += boot_match(&f->ev[i], node, step, status);
	return n;
}

const co_ev_mgr *mf_node_ev(const mf *f, uint8_t node, uint8_t what)
{
	for (unsigned i = f->n_ev; i-- > 0;)
		if (f->ev[i].kind == CO_EV_MGR_NODE && f->ev[i].u.mgr.node == node &&
		    f->ev[i].u.mgr.what == what)
			return &f->ev[i].u.mgr;
	return NULL;
}

unsigned mf_node_count(const mf *f, uint8_t node, uint8_t what)
{
	unsigned n = 0;
	for (unsigned i = 0; i < f->n_ev; i++)
		n += f->ev[i].kind == CO_EV_MGR_NODE && f->ev[i].u.mgr.node == node &&
		     f->ev[i].u.mgr.what == what;
	return n;
}

bool mf_went_through(const mf *f, uint8_t state)
{
	for (unsigned i = 0; i < f->n_ev; i++)
		if (f->ev[i].kind == CO_EV_MGR_STATE && f->ev[i].u.mgr.state == state)
			return true;
	return false;
}

unsigned mf_sent(const mf *f, uint32_t id, const char *hex_prefix)
{
	co_frame want = tb_frame(id, hex_prefix);
	unsigned n = 0;
	for (size_t i = 0; i < f->bus.log_len; i++) {
		const co_frame *fr = &f->bus.log[i];
		if (f->bus.log_from[i] != f->mp->idx || fr->id != id || fr->len < want.len)
			continue;
		n += memcmp(fr->data, want.data, want.len) == 0;
	}
	return n;
}

unsigned mf_max_sdo_in_flight(const mf *f)
{
	bool busy[128] = { false };
	unsigned cur = 0, max = 0;
	for (size_t i = 0; i < f->bus.log_len; i++) {
		const co_frame *fr = &f->bus.log[i];
		if (f->bus.log_from[i] == f->mp->idx && fr->id > 0x600 && fr->id < 0x680) {
			if (!busy[fr->id - 0x600]) {
				busy[fr->id - 0x600] = true;
				if (++cur > max)
					max = cur;
			}
		} else if (fr->id > 0x580 && fr->id < 0x600 && busy[fr->id - 0x580]) {
			busy[fr->id - 0x580] = false;
			cur--;
		}
	}
	return max;
}
