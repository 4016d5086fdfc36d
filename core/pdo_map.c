/* SPDX-License-Identifier: MIT */
/*
 * PDO mapping (CiA 301 §7.5.2.36/38): validation, compilation into
 * (entry, bit offset, bit length) items, bit packing, the allocation of
 * every per-PDO array, and the OD builder co_od_add_pdo().
 *
 * Packing: a classic PDO holds at most 64 bits, so the whole PDO is one
 * uint64_t in CANopen (little-endian, LSB first) bit order. Sampling ORs
 * each object's low `bits` bits in at its offset; receiving shifts them
 * out. No per-bit loops, no special case for bit-sized or odd-length
 * entries.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/pdo_map.h"

#define SLOT_NONE 0xFFFFu

static uint64_t mask_bits(uint8_t bits)
{
	return bits >= 64 ? ~0ull : (1ull << bits) - 1;
}

static uint16_t comm_base(co_pdo_dir d)
{
	return d == CO_PDO_TX ? CO_PDO_TPDO_COMM : CO_PDO_RPDO_COMM;
}

static uint16_t map_base(co_pdo_dir d)
{
	return d == CO_PDO_TX ? CO_PDO_TPDO_MAP : CO_PDO_RPDO_MAP;
}

struct pdo *pdo_of_index(struct co_pdo *P, uint16_t index, bool *is_map)
{
	co_pdo_dir dir;
	uint16_t n, pos;

	if (index < CO_PDO_RPDO_COMM || index >= CO_PDO_TPDO_MAP + CO_PDO_MAX)
		return NULL;
	dir = index >= CO_PDO_TPDO_COMM ? CO_PDO_TX : CO_PDO_RX;
	n = (uint16_t)(index - comm_base(dir));
	*is_map = n >= CO_PDO_MAX;
	if (*is_map)
		n = (uint16_t)(n - CO_PDO_MAX);
	pos = P->slot[dir][n];
	return pos == SLOT_NONE ? NULL : &P->v[pos];
}

/* ---- validation ---------------------------------------------------------- */

/* Is v (index << 16 | sub << 8 | bits) something p may map? */
static uint32_t entry_target(const struct co_pdo *P, co_pdo_dir dir, uint32_t v, co_od_entry **out)
{
	uint16_t index = (uint16_t)(v >> 16);
	uint8_t sub = (uint8_t)(v >> 8), bits = (uint8_t)v;
	uint32_t ab = 0, size;
	co_od_entry *e;
	co_type t;

	*out = NULL;
	if (bits == 0)
		return SDO_AB_NO_MAP;
	if (index >= CO_T_BOOLEAN && index <= CO_T_UNSIGNED32) {
		/* dummy entry: the data type index; RPDO only (CiA 301
		 * §7.4.7.1 defines dummy mapping for receivers) */
		if (dir == CO_PDO_TX)
			return SDO_AB_NO_MAP;
		return bits <= co_type_size((co_type)index) * 8 ? 0 : SDO_AB_NO_MAP;
	}
	e = co_od_find_ex(P->node->od, index, sub, &ab);
	if (!e)
		return ab;
	if (!(e->access & (dir == CO_PDO_TX ? CO_ACC_TPDO : CO_ACC_RPDO)))
		return SDO_AB_NO_MAP;
	t = (co_type)e->type;
	if (t == CO_T_DOMAIN)
		return SDO_AB_NO_MAP;
	if (co_type_is_variable(t)) {
		/* strings: whole bytes, at most the capacity */
		if (bits % 8 || bits / 8u > e->max_size)
			return SDO_AB_NO_MAP;
	} else {
		size = co_type_size(t);
		if (!size || bits > size * 8)
			return SDO_AB_NO_MAP;
		if (co_type_is_real(t) && bits != size * 8)
			return SDO_AB_NO_MAP; /* half a float means nothing */
	}
	*out = e;
	return 0;
}

/* Compile entries 1..n of p's mapping object into items/evmap. */
static uint32_t compile(const struct co_pdo *P, const struct pdo *p, uint8_t n, pdo_item *items,
			co_ev_pdo_map *evmap, uint8_t *len)
{
	uint32_t off = 0;

	if (n > p->cap)
		return n > CO_PDO_MAX_MAP ? SDO_AB_VALUE_HIGH : SDO_AB_MAP_LEN;
	for (uint8_t i = 0; i < n; i++) {
		uint32_t v = (uint32_t)co_od_entry_raw(p->e_map[i]);
		co_od_entry *e;
		uint32_t ab;

		if (v == 0)
			return SDO_AB_NO_MAP;
		ab = entry_target(P, (co_pdo_dir)p->dir, v, &e);
		if (ab)
			return ab;
		if (off + (v & 0xFF) > CO_PDO_MAX_BITS)
			return SDO_AB_MAP_LEN;
		items[i].e = e;
		items[i].off = (uint8_t)off;
		items[i].bits = (uint8_t)v;
		evmap[i].index = (uint16_t)(v >> 16);
		evmap[i].sub = (uint8_t)(v >> 8);
		evmap[i].bits = (uint8_t)v;
		off += v & 0xFF;
	}
	*len = (uint8_t)((off + 7) / 8);
	return 0;
}

bool pdo_map_compile(struct co_pdo *P, struct pdo *p)
{
	uint8_t n = p->e_map0 ? (uint8_t)co_od_entry_raw(p->e_map0) : 0;
	uint8_t len = 0;

	P->rev_dirty = true;
	if (compile(P, p, n, p->items, p->evmap, &len) != 0) {
		p->n = 0;
		p->len = 0;
		p->map_ok = false;
		return false;
	}
	p->n = n;
	p->len = len;
	p->map_ok = true;
	return true;
}

uint32_t pdo_map_check_count(struct co_pdo *P, const struct pdo *p, uint8_t n)
{
	pdo_item items[CO_PDO_MAX_MAP];
	co_ev_pdo_map evmap[CO_PDO_MAX_MAP];
	uint8_t len;

	/* step 2/4 of the CiA sequence need the PDO invalidated (step 1) */
	if (!(p->cob & CO_PDO_COB_INVALID))
		return CO_PDO_AB_SEQUENCE;
	return compile(P, p, n, items, evmap, &len);
}

uint32_t pdo_map_check_entry(struct co_pdo *P, const struct pdo *p, uint32_t v)
{
	co_od_entry *e;

	/* step 3 needs sub 0 = 0 (step 2) */
	if (p->e_map0 && co_od_entry_raw(p->e_map0) != 0)
		return CO_PDO_AB_SEQUENCE;
	if (v == 0)
		return 0; /* clearing an entry is always fine */
	return entry_target(P, (co_pdo_dir)p->dir, v, &e);
}

/* ---- packing ------------------------------------------------------------- */

static uint64_t entry_bits(co_od_entry *e)
{
	if (co_type_is_variable((co_type)e->type))
		return co_get_le(e->data, e->size);
	return co_od_entry_raw(e);
}

void pdo_map_pack(const struct pdo *p, uint8_t out[8])
{
	co_od_access a = { .origin = CO_OD_ORIGIN_PDO };
	uint64_t acc = 0;

	for (uint8_t i = 0; i < p->n; i++) {
		const pdo_item *it = &p->items[i];
		co_od_entry *e = it->e;

		if (!e)
			continue;
		if (e->hooks && e->hooks->read)
			(void)e->hooks->read(e->hook_ctx, e, &a);
		acc |= (entry_bits(e) & mask_bits(it->bits)) << it->off;
	}
	memset(out, 0, 8);
	co_put_le(out, 8, acc);
}

uint32_t pdo_map_unpack_one(const struct pdo *p, uint8_t i, const uint8_t *data, uint8_t len)
{
	const pdo_item *it = &p->items[i];
	co_od_access a = { .origin = CO_OD_ORIGIN_PDO };
	co_od_entry *e = it->e;
	uint8_t bytes[8];
	uint64_t v;
	uint32_t size, ab;
	co_type t;

	if (!e)
		return 0;
	v = (co_get_le(data, len) >> it->off) & mask_bits(it->bits);
	t = (co_type)e->type;
	if (co_type_is_variable(t)) {
		size = it->bits / 8u;
	} else {
		size = e->size;
		if (co_type_is_signed(t) && it->bits < size * 8 && (v >> (it->bits - 1)) & 1)
			v |= ~mask_bits(it->bits); /* sign-extend */
	}
	co_put_le(bytes, size, v);
	a.size = size;
	ab = co_od_write(e, bytes, size, &a);
	return ab;
}

/* ---- object -> TPDO index -------------------------------------------------- */

static int rev_cmp(const void *a, const void *b)
{
	const struct pdo_rev *x = a, *y = b;

	if (x->key != y->key)
		return x->key < y->key ? -1 : 1;
	return (int)x->pdo - (int)y->pdo;
}

void pdo_map_rev_rebuild(struct co_pdo *P)
{
	P->rev_n = 0;
	for (uint16_t k = P->n_rx; k < P->n_rx + P->n_tx; k++) {
		const struct pdo *p = &P->v[k];
		for (uint8_t i = 0; i < p->n; i++) {
			if (!p->items[i].e)
				continue;
			P->rev[P->rev_n].key = (uint32_t)p->evmap[i].index << 8 | p->evmap[i].sub;
			P->rev[P->rev_n].pdo = k;
			P->rev_n++;
		}
	}
	qsort(P->rev, P->rev_n, sizeof(*P->rev), rev_cmp);
	P->rev_dirty = false;
}

/* ---- allocation ------------------------------------------------------------ */

static uint8_t count_map_subs(const co_od *od, uint16_t index)
{
	uint8_t n = 0;

	while (n < CO_PDO_MAX_MAP && co_od_find(od, index, (uint8_t)(n + 1)))
		n++;
	return n;
}

int pdo_map_alloc(struct co_pdo *P)
{
	const co_od *od = P->node->od;
	uint32_t total = 0, rev_total = 0, at = 0;
	uint16_t k = 0, n_all;

	for (int d = 0; d < 2; d++)
		for (uint16_t n = 0; n < CO_PDO_MAX; n++) {
			P->slot[d][n] = SLOT_NONE;
			if (!co_od_find(od, (uint16_t)(comm_base(d) + n), 1))
				continue;
			if (d == CO_PDO_TX)
				P->n_tx++;
			else
				P->n_rx++;
		}
	n_all = (uint16_t)(P->n_rx + P->n_tx);
	P->v = calloc(n_all ? n_all : 1, sizeof(*P->v));
	P->heap = calloc(n_all ? n_all : 1, sizeof(*P->heap));
	P->sync_list = calloc(n_all ? n_all : 1, sizeof(*P->sync_list));
	if (!P->v || !P->heap || !P->sync_list)
		return -ENOMEM;
	for (int d = 0; d < 2; d++)
		for (uint16_t n = 0; n < CO_PDO_MAX; n++) {
			uint16_t ci = (uint16_t)(comm_base(d) + n);
			uint16_t mi = (uint16_t)(map_base(d) + n);
			struct pdo *p;

			if (!co_od_find(od, ci, 1))
				continue;
			p = &P->v[k];
			P->slot[d][n] = k++;
			p->nr = (uint16_t)(n + 1);
			p->dir = (uint8_t)d;
			p->rx_h = -1;
			p->hpos = SLOT_NONE;
			p->timer_us = CO_NO_DEADLINE;
			for (uint8_t s = 0; s <= 6; s++)
				p->e_comm[s] = co_od_find(od, ci, s);
			p->e_map0 = co_od_find(od, mi, 0);
			p->cap = p->e_map0 ? count_map_subs(od, mi) : 0;
			total += p->cap;
			if (d == CO_PDO_TX)
				rev_total += p->cap;
		}
	P->entry_pool = calloc(total ? total : 1, sizeof(*P->entry_pool));
	P->item_pool = calloc(total ? total : 1, sizeof(*P->item_pool));
	P->evmap_pool = calloc(total ? total : 1, sizeof(*P->evmap_pool));
	P->rev = calloc(rev_total ? rev_total : 1, sizeof(*P->rev));
	if (!P->entry_pool || !P->item_pool || !P->evmap_pool || !P->rev)
		return -ENOMEM;
	for (k = 0; k < n_all; k++) {
		struct pdo *p = &P->v[k];
		uint16_t mi = (uint16_t)(map_base((co_pdo_dir)p->dir) + p->nr - 1);

		p->e_map = P->entry_pool + at;
		p->items = P->item_pool + at;
		p->evmap = P->evmap_pool + at;
		for (uint8_t i = 0; i < p->cap; i++)
			p->e_map[i] = co_od_find(od, mi, (uint8_t)(i + 1));
		at += p->cap;
	}
	P->rev_dirty = true;
	P->sync_dirty = true;
	return 0;
}

void pdo_map_free(struct co_pdo *P)
{
	free(P->rev);
	free(P->evmap_pool);
	free(P->item_pool);
	free(P->entry_pool);
	free(P->sync_list);
	free(P->heap);
	free(P->v);
}

/* ---- OD builder ------------------------------------------------------------- */

static int add_rec(co_od *od, uint16_t index, uint8_t sub, co_type t, uint16_t access, uint64_t def)
{
	uint8_t b[8];
	co_od_desc d = {
		.index = index,
		.sub = sub,
		.obj_code = CO_OBJ_RECORD,
		.type = (uint8_t)t,
		.access = access,
		.def = b,
		.def_size = co_type_size(t),
	};

	co_put_le(b, 8, def);
	return co_od_add(od, &d, NULL);
}

int co_od_add_pdo(co_od *od, const co_pdo_desc *d)
{
	uint16_t ci, mi;
	uint8_t subs;
	int rc;

	if (!od || !d || d->nr < 1 || d->nr > CO_PDO_MAX || d->map_subs > CO_PDO_MAX_MAP ||
	    (d->n_map && !d->map))
		return -EINVAL;
	subs = d->map_subs ? d->map_subs : 8;
	if (d->n_map > subs)
		return -EINVAL;
	ci = (uint16_t)(comm_base(d->dir) + d->nr - 1);
	mi = (uint16_t)(map_base(d->dir) + d->nr - 1);
	if (co_od_has_index(od, ci) || co_od_has_index(od, mi))
		return -EEXIST;
	rc = add_rec(od, ci, 0, CO_T_UNSIGNED8, CO_ACC_RO, d->dir == CO_PDO_TX ? 6 : 5);
	if (!rc)
		rc = add_rec(od, ci, 1, CO_T_UNSIGNED32, CO_ACC_RW, d->cob_id);
	if (!rc)
		rc = add_rec(od, ci, 2, CO_T_UNSIGNED8, CO_ACC_RW, d->tt);
	if (!rc)
		rc = add_rec(od, ci, 3, CO_T_UNSIGNED16, CO_ACC_RW, d->inhibit_100us);
	if (!rc)
		rc = add_rec(od, ci, 5, CO_T_UNSIGNED16, CO_ACC_RW, d->event_ms);
	if (!rc && d->dir == CO_PDO_TX)
		rc = add_rec(od, ci, 6, CO_T_UNSIGNED8, CO_ACC_RW, d->sync_start);
	if (!rc)
		rc = add_rec(od, mi, 0, CO_T_UNSIGNED8, CO_ACC_RW, d->n_map);
	for (uint8_t i = 0; !rc && i < subs; i++)
		rc = add_rec(od, mi, (uint8_t)(i + 1), CO_T_UNSIGNED32, CO_ACC_RW,
			     i < d->n_map ? d->map[i] : 0);
	return rc;
}
