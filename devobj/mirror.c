/* SPDX-License-Identifier: MIT */
/*
 * devobj/mirror.c - the daemon's PDOs that mirror its slaves' PDOs
 * (devobj/mirror.h, docs/devices.md "Automatic mirroring").
 */
#include "devobj/mirror.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/frame.h"
#include "core/od.h"

/* CAN-ID and frame format of a COB-ID (CiA 301 §7.5.2.35: bits 0..28 and
 * bit 29); bits 30/31 say nothing about which frames it means. */
#define COB_FRAME_BITS (0x1FFFFFFFu | CO_PDO_COB_EXT)

const char *devobj_reason_to_string(uint8_t r)
{
	static const char *const names[DEVOBJ_R_COUNT] = {
		[DEVOBJ_R_NONE] = "none",
		[DEVOBJ_R_NO_RECORD] = "no-free-pdo",
		[DEVOBJ_R_COB_IN_USE] = "cob-id-in-use",
		[DEVOBJ_R_OD_REFUSED] = "od-refused",
		[DEVOBJ_R_NOT_KEPT] = "not-kept",
	};
	return r < DEVOBJ_R_COUNT ? names[r] : "?";
}

const char *devobj_mirror_status_to_string(uint8_t s)
{
	static const char *const names[] = { "off", "waiting", "full", "partial", "none" };
	return s < sizeof names / sizeof names[0] ? names[s] : "?";
}

static uint16_t comm_index(co_pdo_dir d, uint16_t nr)
{
	return (uint16_t)((d == CO_PDO_RX ? CO_PDO_RPDO_COMM : CO_PDO_TPDO_COMM) + nr - 1u);
}

static uint16_t map_index(co_pdo_dir d, uint16_t nr)
{
	return (uint16_t)((d == CO_PDO_RX ? CO_PDO_RPDO_MAP : CO_PDO_TPDO_MAP) + nr - 1u);
}

static uint16_t slot_index(co_pdo_dir d)
{
	return d == CO_PDO_RX ? DEVOBJ_SLOT_RX_INDEX : DEVOBJ_SLOT_TX_INDEX;
}

/* Left alone by the configuration (and by SDO clients since): invalid and
 * nothing mapped. */
static bool record_is_free(const co_od *od, co_pdo_dir d, uint16_t nr, uint32_t *cob)
{
	uint8_t n_map = 1;
	*cob = 0;
	if (co_od_get_u32(od, comm_index(d, nr), 1, cob) < 0 ||
	    co_od_get_u8(od, map_index(d, nr), 0, &n_map) < 0)
		return false;
	return (*cob & CO_PDO_COB_INVALID) && n_map == 0 && co_od_find(od, map_index(d, nr), 1);
}

/* One step of the re-mapping, checked by the PDO service like an SDO
 * write would be (its hooks run). Returns 0 or the abort code. */
static uint32_t od_write(co_od *od, uint16_t index, uint8_t sub, uint64_t value)
{
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(od, index, sub, &abort);
	if (!e)
		return abort;
	uint8_t buf[8];
	co_put_le(buf, e->size, value);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL, .data = buf, .size = e->size };
	return co_od_write(e, buf, e->size, &a);
}

static int alloc_node(devobj_node_mirror *nm, uint16_t cap)
{
	for (int d = 0; d < 2; d++) {
		nm->rec[d] = malloc((size_t)cap * sizeof *nm->rec[d]);
		nm->why[d] = calloc(cap, sizeof *nm->why[d]);
		if (!nm->rec[d] || !nm->why[d])
			return -ENOMEM;
		for (unsigned i = 0; i < cap; i++)
			nm->rec[d][i] = -1;
	}
	return 0;
}

static int create_records(devobj_mirror *m, co_pdo_dir d)
{
	co_od *od = co_node_od(m->co);
	uint16_t count = co_pdo_count(m->co, d);

	m->n_nr[d] = (uint16_t)(count + 1u);
	m->rec_of_nr[d] = malloc(m->n_nr[d] * sizeof *m->rec_of_nr[d]);
	m->rec[d] = calloc(count ? count : 1u, sizeof *m->rec[d]);
	if (!m->rec_of_nr[d] || !m->rec[d])
		return -ENOMEM;
	for (unsigned nr = 0; nr <= count; nr++)
		m->rec_of_nr[d][nr] = -1;
	for (uint16_t nr = 1; nr <= count && m->n_rec[d] < DEVOBJ_SLOTS_MAX; nr++) {
		uint32_t cob;
		if (!record_is_free(od, d, nr, &cob))
			continue;
		devobj_record *r = &m->rec[d][m->n_rec[d]];
		r->nr = nr;
		r->slot_sub = (uint8_t)(m->n_rec[d] + 1u);
		r->idle_cob = cob;
		m->rec_of_nr[d][nr] = (int16_t)m->n_rec[d];
		m->n_rec[d]++;
	}
	if (!m->n_rec[d])
		return 0;
	if (co_od_has_index(od, slot_index(d)))
		return -EEXIST;
	/* mappable the way the daemon's PDO of that direction maps it; read
	 * over SDO for diagnosis, never written but by the mirror */
	uint16_t access = CO_ACC_READ | (d == CO_PDO_RX ? CO_ACC_RPDO : CO_ACC_TPDO);
	return co_od_add_array(od, slot_index(d), CO_T_UNSIGNED64, (uint8_t)m->n_rec[d], access, 0);
}

static bool bit_of(const uint32_t *bits, unsigned id)
{
	return bits && ((bits[id / 32u] >> (id % 32u)) & 1u);
}

int devobj_mirror_create(devobj_mirror *m, co_node *co, co_pdo_layout *layout,
			 const uint32_t wanted[4], const uint32_t room[4])
{
	int rc = 0;
	bool any = false;

	memset(m, 0, sizeof *m);
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++)
		any |= bit_of(wanted, id) || bit_of(room, id);
	if (!any || !layout)
		return 0;
	m->co = co;
	m->layout = layout;
	if ((rc = create_records(m, CO_PDO_RX)) < 0 || (rc = create_records(m, CO_PDO_TX)) < 0)
		goto fail;
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++) {
		devobj_node_mirror *nm = &m->node[id];
		const co_pdo_layout_node *ln = co_pdo_layout_node_get(layout, (uint8_t)id);
		if ((!bit_of(wanted, id) && !bit_of(room, id)) || !ln)
			continue;
		nm->wanted = bit_of(wanted, id);
		nm->status = nm->wanted ? DEVOBJ_M_WAITING : DEVOBJ_M_OFF;
		if ((rc = alloc_node(nm, ln->cap)) < 0)
			goto fail;
	}
	return 0;
fail:
	devobj_mirror_destroy(m);
	return rc;
}

void devobj_mirror_destroy(devobj_mirror *m)
{
	for (int d = 0; d < 2; d++) {
		free(m->rec[d]);
		free(m->rec_of_nr[d]);
		for (unsigned id = 0; id <= CO_PDO_LAYOUT_NODES; id++) {
			free(m->node[id].rec[d]);
			free(m->node[id].why[d]);
		}
	}
	memset(m, 0, sizeof *m);
}

static void release(devobj_mirror *m, co_pdo_dir d, devobj_record *r)
{
	co_od *od = co_node_od(m->co);
	/* CiA 301 §7.5.2.36: invalid first, then the mapping may go */
	od_write(od, comm_index(d, r->nr), 1, r->idle_cob | CO_PDO_COB_INVALID);
	od_write(od, map_index(d, r->nr), 0, 0);
	r->busy = false;
}

/* A valid PDO of the daemon in direction d already on that CAN-ID. */
static bool cob_in_use(const devobj_mirror *m, co_pdo_dir d, uint32_t cob)
{
	const co_od *od = co_node_od(m->co);
	uint16_t count = co_pdo_count(m->co, d);
	for (uint16_t nr = 1; nr <= count; nr++) {
		uint32_t v;
		if (co_pdo_is_valid(m->co, d, nr) &&
		    co_od_get_u32(od, comm_index(d, nr), 1, &v) == 0 &&
		    (v & COB_FRAME_BITS) == (cob & COB_FRAME_BITS))
			return true;
	}
	return false;
}

static devobj_record *free_record(devobj_mirror *m, co_pdo_dir d)
{
	const co_od *od = co_node_od(m->co);
	for (unsigned i = 0; i < m->n_rec[d]; i++) {
		devobj_record *r = &m->rec[d][i];
		uint32_t cob;
		if (!r->busy && record_is_free(od, d, r->nr, &cob))
			return r;
	}
	return NULL;
}

/* The deadline (CiA 301 §7.5.2.35, the RPDO's event timer) of the daemon's
 * RPDO mirroring device TPDO p: a TPDO of an event-driven type (254, 255)
 * with an event timer is sent at least every event timer; twice that is
 * missed only when a whole frame is missing, never by the jitter of the
 * device's timer or of the bus (docs/devices.md "Supervision"). 0 = none:
 * a synchronous or RTR-only TPDO, or one without an event timer. */
static uint16_t mirror_deadline_ms(const co_pdo_layout_pdo *p)
{
	if (p->tt < CO_PDO_TT_EVENT_MANUF || p->event_ms == 0)
		return 0;
	uint32_t ms = 2u * p->event_ms;
	return ms > UINT16_MAX ? UINT16_MAX : (uint16_t)ms;
}

/* Program record r (daemon direction d) for the device PDO p: CiA 301
 * §7.5.2.36 re-mapping through the OD. 0 or the abort code of the step the
 * OD refused. */
static uint32_t program(devobj_mirror *m, co_pdo_dir d, const devobj_record *r,
			const co_pdo_layout_pdo *p)
{
	co_od *od = co_node_od(m->co);
	uint16_t comm = comm_index(d, r->nr), map = map_index(d, r->nr);
	/* the daemon consumes as soon as a frame arrives and produces when a
	 * client's values are complete: event-driven both ways (docs/devices.md);
	 * a consumed TPDO is supervised when the device promises a period */
	uint32_t cob = (p->cob & COB_FRAME_BITS) | (d == CO_PDO_TX ? CO_PDO_COB_NO_RTR : 0u);
	uint16_t timer_ms = d == CO_PDO_RX ? mirror_deadline_ms(p) : 0;
	uint32_t abort;

	if ((abort = od_write(od, comm, 1, r->idle_cob | CO_PDO_COB_INVALID)) ||
	    (abort = od_write(od, map, 0, 0)) ||
	    (abort = od_write(od, map, 1,
			      CO_PDO_MAP(slot_index(d), r->slot_sub, (uint32_t)p->bytes * 8u))) ||
	    (abort = od_write(od, map, 0, 1)) ||
	    (abort = od_write(od, comm, 2, CO_PDO_TT_EVENT_PROFILE)) ||
	    (abort = od_write(od, comm, 5, timer_ms)))
		return abort;
	if (d == CO_PDO_TX && (abort = od_write(od, comm, 3, 0)))
		return abort;
	return od_write(od, comm, 1, cob);
}

static uint8_t mirror_one(devobj_mirror *m, uint8_t id, co_pdo_dir dev_dir, uint16_t pos,
			  const co_pdo_layout_pdo *p)
{
	co_pdo_dir d = dev_dir == CO_PDO_TX ? CO_PDO_RX : CO_PDO_TX;
	if (p->bytes == 0)
		return DEVOBJ_R_OD_REFUSED; /* nothing mapped: a frame of 0 bits */
	if (cob_in_use(m, d, p->cob))
		return DEVOBJ_R_COB_IN_USE;
	devobj_record *r = free_record(m, d);
	if (!r)
		return DEVOBJ_R_NO_RECORD;
	if (program(m, d, r, p)) {
		release(m, d, r);
		return DEVOBJ_R_OD_REFUSED;
	}
	r->busy = true;
	r->node = id;
	r->dev_pos = pos;
	m->node[id].rec[dev_dir][pos] = (int16_t)(r - m->rec[d]);
	return DEVOBJ_R_NONE;
}

static void release_node(devobj_mirror *m, uint8_t id, uint16_t cap)
{
	devobj_node_mirror *nm = &m->node[id];
	for (int dev_dir = 0; dev_dir < 2; dev_dir++) {
		co_pdo_dir d = dev_dir == CO_PDO_TX ? CO_PDO_RX : CO_PDO_TX;
		for (unsigned pos = 0; pos < cap; pos++) {
			int16_t k = nm->rec[dev_dir][pos];
			if (k >= 0 && m->rec[d][k].busy)
				release(m, d, &m->rec[d][k]);
			nm->rec[dev_dir][pos] = -1;
			nm->why[dev_dir][pos] = DEVOBJ_R_NONE;
		}
	}
	nm->missing = 0;
	nm->reason = DEVOBJ_R_NONE;
}

int devobj_mirror_want(devobj_mirror *m, uint8_t id, bool on)
{
	devobj_node_mirror *nm = id >= 1 && id <= CO_PDO_LAYOUT_NODES ? &m->node[id] : NULL;
	const co_pdo_layout_node *ln = nm && m->layout ? co_pdo_layout_node_get(m->layout, id)
						       : NULL;

	if (!ln || !nm->rec[0])
		return on ? -ENOSPC : 0;
	if (nm->wanted && !on)
		release_node(m, id, ln->cap);
	nm->wanted = on;
	nm->status = on ? DEVOBJ_M_WAITING : DEVOBJ_M_OFF;
	nm->generation = 0;
	nm->stale = on; /* programmed at the next sync, whatever the layout's generation */
	return 0;
}

bool devobj_mirror_sync(devobj_mirror *m, uint8_t id)
{
	devobj_node_mirror *nm = id <= CO_PDO_LAYOUT_NODES ? &m->node[id] : NULL;
	if (!nm || !nm->wanted)
		return false;
	const co_pdo_layout_node *ln = co_pdo_layout_node_get(m->layout, id);
	if (ln->generation == nm->generation && !nm->stale)
		return false;
	nm->stale = false;
	release_node(m, id, ln->cap);
	nm->generation = ln->generation;
	nm->status = DEVOBJ_M_WAITING;
	if (!ln->valid)
		return true;

	unsigned total = 0;
	for (int dev_dir = 0; dev_dir < 2; dev_dir++) {
		for (uint16_t pos = 0; pos < ln->n[dev_dir]; pos++) {
			uint8_t why = mirror_one(m, id, (co_pdo_dir)dev_dir, pos,
						 &ln->pdo[dev_dir][pos]);
			nm->why[dev_dir][pos] = why;
			total++;
			if (why != DEVOBJ_R_NONE) {
				nm->missing++;
				if (nm->reason == DEVOBJ_R_NONE)
					nm->reason = why;
			}
		}
		if (ln->dropped[dev_dir]) {
			total += ln->dropped[dev_dir];
			nm->missing = (uint16_t)(nm->missing + ln->dropped[dev_dir]);
			if (nm->reason == DEVOBJ_R_NONE)
				nm->reason = DEVOBJ_R_NOT_KEPT;
		}
	}
	m->refused += nm->missing;
	nm->status = nm->missing == 0      ? DEVOBJ_M_FULL
		     : nm->missing < total ? DEVOBJ_M_PARTIAL
					   : DEVOBJ_M_NONE;
	return true;
}

void devobj_mirror_forget(devobj_mirror *m)
{
	m->resets++;
	for (int d = 0; d < 2; d++)
		for (unsigned i = 0; i < m->n_rec[d]; i++)
			m->rec[d][i].busy = false;
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++) {
		devobj_node_mirror *nm = &m->node[id];
		const co_pdo_layout_node *ln = m->layout ? co_pdo_layout_node_get(m->layout,
										  (uint8_t)id)
							 : NULL;
		if (!nm->wanted || !ln)
			continue;
		for (int dev_dir = 0; dev_dir < 2; dev_dir++)
			for (unsigned pos = 0; pos < ln->cap; pos++)
				nm->rec[dev_dir][pos] = -1;
		nm->stale = true;
	}
}

uint32_t devobj_mirror_keep_sending(devobj_mirror *m, const devobj_record *r, uint16_t period_ms)
{
	return od_write(co_node_od(m->co), comm_index(CO_PDO_TX, r->nr), 5, period_ms);
}

const devobj_record *devobj_mirror_record_of(const devobj_mirror *m, co_pdo_dir dir, uint16_t nr)
{
	if (!m->rec_of_nr[dir] || nr >= m->n_nr[dir])
		return NULL;
	int16_t k = m->rec_of_nr[dir][nr];
	return k >= 0 && m->rec[dir][k].busy ? &m->rec[dir][k] : NULL;
}

int devobj_mirror_record_for(const devobj_mirror *m, uint8_t id, co_pdo_dir dev_dir, uint16_t pos)
{
	const devobj_node_mirror *nm = id <= CO_PDO_LAYOUT_NODES ? &m->node[id] : NULL;
	if (!nm || !nm->wanted || !nm->rec[dev_dir])
		return -1;
	const co_pdo_layout_node *ln = co_pdo_layout_node_get(m->layout, id);
	if (!ln || pos >= ln->cap)
		return -1;
	return nm->rec[dev_dir][pos];
}
