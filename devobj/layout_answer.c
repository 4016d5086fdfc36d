/* SPDX-License-Identifier: MIT */
/*
 * devobj/layout_answer.c - DEV_LAYOUT: the learned PDO layouts of the
 * line's slaves with what the mirror made of them (docs/mailbox.md
 * "Device objects" gives the wire format).
 */
#include <string.h>

#include "devobj/devobj_int.h"

static size_t node_max(uint16_t cap)
{
	size_t per_pdo = sizeof(mbx_dev_layout_pdo) + CO_PDO_MAX_MAP * sizeof(mbx_dev_layout_entry);
	return sizeof(mbx_dev_layout_node) + 2u * cap * per_pdo;
}

size_t devobj_layout_answer_max(const devobj_line *dl)
{
	const co_pdo_layout *t = line_pdo_layout(dl->l);
	size_t total = 0;
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++) {
		const co_pdo_layout_node *n = co_pdo_layout_node_get(t, (uint8_t)id);
		if (n)
			total += node_max(n->cap);
	}
	return total ? total : 1u;
}

static size_t put_pdos(const devobj_line *dl, uint8_t id, const co_pdo_layout_node *n,
		       co_pdo_dir dev_dir, uint8_t *out)
{
	const devobj_node_mirror *nm = &dl->mirror.node[id];
	co_pdo_dir d = dev_dir == CO_PDO_TX ? CO_PDO_RX : CO_PDO_TX;
	size_t off = 0;
	for (uint16_t k = 0; k < n->n[dev_dir]; k++) {
		const co_pdo_layout_pdo *p = &n->pdo[dev_dir][k];
		int rec = devobj_mirror_record_for(&dl->mirror, id, dev_dir, k);
		mbx_dev_layout_pdo w = {
			.nr = p->nr,
			.dir = dev_dir == CO_PDO_TX,
			.n = p->n,
			.cob = p->cob,
			.tt = p->tt,
			.sync_start = p->sync_start,
			.inhibit = p->inhibit,
			.event_ms = p->event_ms,
			.bytes = p->bytes,
			.mirror_reason = nm->why[dev_dir] ? nm->why[dev_dir][k] : 0,
			.mirror_pdo = rec >= 0 ? dl->mirror.rec[d][rec].nr : 0,
		};
		memcpy(out + off, &w, sizeof w);
		off += sizeof w;
		for (unsigned i = 0; i < p->n; i++) {
			const co_pdo_layout_entry *e = &p->map[i];
			mbx_dev_layout_entry we = { .index = e->index,
						    .sub = e->sub,
						    .bits = e->bits,
						    .offset = e->offset,
						    .access = e->access,
						    .type = e->type };
			memcpy(out + off, &we, sizeof we);
			off += sizeof we;
		}
	}
	return off;
}

static size_t put_node(const devobj_line *dl, uint8_t id, const co_pdo_layout_node *n, uint8_t *out)
{
	const devobj_node_mirror *nm = &dl->mirror.node[id];
	mbx_dev_layout_node w = {
		.node = id,
		.source = n->source,
		.valid = n->valid,
		.mirror = nm->wanted ? nm->status : DEVOBJ_M_OFF,
		.reason = nm->reason,
		.missing = nm->missing,
		.generation = n->generation,
		.n_tpdo = n->n[CO_PDO_TX],
		.n_rpdo = n->n[CO_PDO_RX],
		.dropped_tpdo = n->dropped[CO_PDO_TX],
		.dropped_rpdo = n->dropped[CO_PDO_RX],
		.learned_us = n->learned_us,
	};
	memcpy(out, &w, sizeof w);
	size_t off = sizeof w;
	off += put_pdos(dl, id, n, CO_PDO_TX, out + off);
	off += put_pdos(dl, id, n, CO_PDO_RX, out + off);
	return off;
}

void devobj_cmd_layout(devobj_line *dl, const mbx_request *req)
{
	mbx_dev_node_req r;
	const co_pdo_layout *t = line_pdo_layout(dl->l);
	size_t len = 0;
	memcpy(&r, req->payload, sizeof r);

	if (r.node) {
		const co_pdo_layout_node *n = co_pdo_layout_node_get(t, r.node);
		if (!n)
			return devobj_answer(dl, &req->reply, MBX_E_NOT_FOUND, 0, NULL, 0);
		len = put_node(dl, r.node, n, dl->layout_buf);
	} else {
		for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++) {
			const co_pdo_layout_node *n = co_pdo_layout_node_get(t, (uint8_t)id);
			if (n)
				len += put_node(dl, (uint8_t)id, n, dl->layout_buf + len);
		}
	}
	devobj_answer(dl, &req->reply, 0, 0, dl->layout_buf, len);
}

/* The wire's numbers are the mirror's own (devobj/mirror.h). */
_Static_assert((int)DEVOBJ_M_OFF == (int)MBX_DEV_MIRROR_OFF &&
		       (int)DEVOBJ_M_WAITING == (int)MBX_DEV_MIRROR_WAITING &&
		       (int)DEVOBJ_M_FULL == (int)MBX_DEV_MIRROR_FULL &&
		       (int)DEVOBJ_M_PARTIAL == (int)MBX_DEV_MIRROR_PARTIAL &&
		       (int)DEVOBJ_M_NONE == (int)MBX_DEV_MIRROR_NONE,
	       "mirror status numbers");
_Static_assert((int)DEVOBJ_R_NO_RECORD == (int)MBX_DEV_MR_NO_FREE_PDO &&
		       (int)DEVOBJ_R_COB_IN_USE == (int)MBX_DEV_MR_COB_IN_USE &&
		       (int)DEVOBJ_R_OD_REFUSED == (int)MBX_DEV_MR_OD_REFUSED &&
		       (int)DEVOBJ_R_NOT_KEPT == (int)MBX_DEV_MR_NOT_KEPT,
	       "mirror reason numbers");
