/* SPDX-License-Identifier: MIT */
/*
 * devobj/read_write.c - DEV_READ and DEV_WRITE (docs/devices.md "Reading
 * and writing"): a read answers from the mirror when the value is fresh
 * enough, else by SDO; a write goes into the frame of the device's RPDO
 * the mirror produces (sent once every object of it has a value, at most
 * one frame per update time), else by SDO. The SDO transfers are the
 * line's own mailbox transfers (line_sdo_submit); the answer says which
 * way it went.
 *
 * Access rules as an SDO server applies them (CiA 301 §7.4.5): where the
 * node's file gives an object's access, a read-only object refuses a write
 * with 06010002 and a write-only one a read with 06010001 before anything
 * goes on the bus; a value of the wrong length is refused with
 * 06070012/06070013. Where nothing is known the device decides.
 */
#include <string.h>

#include "core/frame.h"
#include "core/od.h"
#include "core/pdo.h"
#include "core/sdo.h"
#include "devobj/devobj_int.h"
#include "devobj/value.h"

/* What the line knows of the object: its type and access from the layout
 * (either direction), else from the node's file; 0 where unknown. */
static void known(const devobj_line *dl, const mbx_dev_obj_req *o, uint16_t *type, uint8_t *access)
{
	devobj_place at;
	*type = 0;
	*access = 0;
	if (devobj_find(dl, o->node, CO_PDO_TX, o->index, o->sub, &at) ||
	    devobj_find(dl, o->node, CO_PDO_RX, o->index, o->sub, &at)) {
		*type = at.entry->type;
		*access = at.entry->access;
	}
	const devobj_node_objects *objs = &dl->p.objects[o->node];
	const co_pdo_layout_type *t = co_pdo_layout_type_find(objs->list, objs->n, o->index,
							      o->sub);
	if (t && !*type)
		*type = t->type;
	if (t && !*access)
		*access = t->access;
}

/* A read or write of object o as an SDO server would take it: the type
 * the client asked for against the one the line knows (*type), the access
 * the node's file gives. 0 or the abort code. */
static uint32_t check_access(const devobj_line *dl, const mbx_dev_obj_req *o, bool write,
			     uint16_t *type)
{
	uint8_t access;
	known(dl, o, type, &access);
	if (o->type && *type && o->type != *type)
		return SDO_AB_TYPE_LEN;
	if (!access)
		return 0;
	if (write)
		return !(access & CO_ACC_WRITE) || (access & CO_ACC_CONST) ? SDO_AB_READ_ONLY : 0;
	return !(access & CO_ACC_READ) ? SDO_AB_WRITE_ONLY : 0;
}

/* ---- SDO fall-back ------------------------------------------------------------ */

static devobj_sdo_call *take_call(devobj_line *dl, const mbx_dev_obj_req *o, uint16_t type)
{
	for (unsigned i = 0; i < DEVOBJ_SDO_CALLS; i++) {
		devobj_sdo_call *c = &dl->calls[i];
		if (c->used)
			continue;
		*c = (devobj_sdo_call){ .used = true,
					.dl = dl,
					.node = o->node,
					.sub = o->sub,
					.index = o->index,
					.type = type };
		return c;
	}
	return NULL;
}

/* The type of an uploaded value nobody named: an UNSIGNEDn of its length,
 * a DOMAIN beyond 8 bytes. */
static uint16_t type_of_length(uint32_t len)
{
	static const uint16_t by_len[9] = { CO_T_DOMAIN,     CO_T_UNSIGNED8,  CO_T_UNSIGNED16,
					    CO_T_UNSIGNED24, CO_T_UNSIGNED32, CO_T_UNSIGNED40,
					    CO_T_UNSIGNED48, CO_T_UNSIGNED56, CO_T_UNSIGNED64 };
	return len <= 8u ? by_len[len] : CO_T_DOMAIN;
}

static void read_answer(void *ctx, line *l, const mbx_reply_to *to, uint32_t abort,
			const uint8_t *data, uint32_t len)
{
	devobj_sdo_call *c = ctx;
	devobj_line *dl = c->dl;
	uint16_t type = c->type ? c->type : type_of_length(len);
	c->used = false;
	if (abort)
		return devobj_answer(dl, to, MBX_E_ABORT, abort, NULL, 0);
	uint32_t size = co_type_size((co_type)type);
	if (size && len != size)
		return devobj_answer(dl, to, MBX_E_ABORT, SDO_AB_TYPE_LEN, NULL, 0);
	/* the value follows the fixed part, in one answer (chunked by the
	 * mailbox when it is longer than a message) */
	mbx_dev_value v = {
		.node = c->node,
		.sub = c->sub,
		.index = c->index,
		.type = type,
		.via = MBX_DEV_VIA_SDO,
		.time_us = line_loop_now_us(l),
		.len = len,
	};
	if (len > DEVOBJ_READ_MAX)
		return devobj_answer(dl, to, MBX_E_TOO_BIG, 0, NULL, 0);
	memcpy(dl->read_buf, &v, sizeof v);
	memcpy(dl->read_buf + sizeof v, data, len);
	devobj_answer(dl, to, 0, 0, dl->read_buf, sizeof v + len);
}

static void write_answer(void *ctx, line *l, const mbx_reply_to *to, uint32_t abort,
			 const uint8_t *data, uint32_t len)
{
	devobj_sdo_call *c = ctx;
	(void)l;
	(void)data;
	(void)len;
	c->used = false;
	if (abort)
		return devobj_answer(c->dl, to, MBX_E_ABORT, abort, NULL, 0);
	mbx_dev_write_resp resp = { .via = MBX_DEV_VIA_SDO };
	devobj_answer(c->dl, to, 0, 0, &resp, sizeof resp);
}

static void by_sdo(devobj_line *dl, const mbx_request *req, const mbx_dev_obj_req *o, uint16_t type,
		   bool upload)
{
	devobj_sdo_call *c = take_call(dl, o, type);
	if (!c)
		return devobj_answer(dl, &req->reply, MBX_E_BUSY, 0, NULL, 0);
	line_sdo_xfer x = {
		.upload = upload,
		.node = o->node,
		.index = o->index,
		.sub = o->sub,
		.size_hint = upload ? co_type_size((co_type)type) : 0,
		.answer = upload ? read_answer : write_answer,
		.ctx = c,
	};
	if (!line_sdo_submit(dl->l, req, &x))
		c->used = false; /* refused and answered */
}

/* ---- DEV_READ ----------------------------------------------------------------- */

void devobj_cmd_read(devobj_line *dl, const mbx_request *req)
{
	mbx_dev_read_req r;
	uint16_t type;
	devobj_place at;
	memcpy(&r, req->payload, sizeof r);

	uint32_t abort = check_access(dl, &r.obj, false, &type);
	if (abort)
		return devobj_answer(dl, &req->reply, MBX_E_ABORT, abort, NULL, 0);

	uint64_t now = line_loop_now_us(dl->l);
	uint64_t max_age_us = (uint64_t)(r.max_age_ms ? r.max_age_ms : dl->p.read_max_age_ms) *
			      1000u;
	if (!(r.obj.flags & MBX_DEV_SDO_ONLY) &&
	    devobj_find(dl, r.obj.node, CO_PDO_TX, r.obj.index, r.obj.sub, &at) && at.rec >= 0) {
		const devobj_rx *rx = &dl->rx[at.rec];
		uint64_t age = now - rx->time_us;
		uint16_t vt = devobj_value_type(at.entry, r.obj.type);
		if (!vt)
			return devobj_answer(dl, &req->reply, MBX_E_ABORT, SDO_AB_TYPE_LEN, NULL,
					     0);
		if (rx->count && (r.max_age_ms == UINT32_MAX || age <= max_age_us)) {
			uint8_t buf[sizeof(mbx_dev_value) + 8];
			mbx_dev_value v = {
				.node = r.obj.node,
				.sub = r.obj.sub,
				.index = r.obj.index,
				.type = vt,
				.via = MBX_DEV_VIA_PDO,
				.bits = at.entry->bits,
				.seq = rx->count,
				.age_ms = (uint32_t)(age / 1000u > UINT32_MAX ? UINT32_MAX
									      : age / 1000u),
				.time_us = rx->time_us,
			};
			v.len = devobj_value_extract(rx->frame, at.entry, vt, buf + sizeof v);
			memcpy(buf, &v, sizeof v);
			return devobj_answer(dl, &req->reply, 0, 0, buf, sizeof v + v.len);
		}
	}
	by_sdo(dl, req, &r.obj, r.obj.type ? r.obj.type : type, true);
}

/* ---- DEV_WRITE ---------------------------------------------------------------- */

/* Every entry of the device RPDO has been given a value (dummy entries,
 * 0001h..0007h, carry none: CiA 301 §7.4.7.1). */
static bool complete(const co_pdo_layout_pdo *p, uint64_t given)
{
	for (unsigned i = 0; i < p->n; i++)
		if (p->map[i].index > 0x0007u && !((given >> i) & 1u))
			return false;
	return true;
}

bool devobj_tx_given(devobj_line *dl, const devobj_place *at, bool at_once)
{
	devobj_tx *tx = &dl->tx[at->rec];
	tx->given |= (uint64_t)1 << at->pos;
	bool held = !complete(at->pdo, tx->given);
	uint64_t now = line_loop_now_us(dl->l);
	if (!held && !tx->dirty)
		dl->n_dirty++;
	if (!held && at_once) {
		tx->due_us = now;
	} else if (!held && !tx->dirty) {
		/* coalesced: at most one frame per update time, carrying the
		 * latest value of each object (docs/devices.md) */
		uint64_t earliest = tx->sent ? tx->sent_us + (uint64_t)dl->p.write_update_ms * 1000u
					     : now;
		tx->due_us = earliest > now ? earliest : now;
	}
	tx->dirty = !held;
	return held;
}

static void by_pdo(devobj_line *dl, const mbx_request *req, const mbx_dev_obj_req *o,
		   const devobj_place *at)
{
	devobj_tx *tx = &dl->tx[at->rec];
	uint16_t type = devobj_value_type(at->entry, o->type);
	if (!type)
		return devobj_answer(dl, &req->reply, MBX_E_ABORT, SDO_AB_TYPE_LEN, NULL, 0);
	uint32_t abort = devobj_value_insert(tx->frame, at->entry, type, req->data,
					     (uint32_t)req->data_len);
	if (abort)
		return devobj_answer(dl, &req->reply, MBX_E_ABORT, abort, NULL, 0);
	bool held = devobj_tx_given(dl, at, false);
	mbx_dev_write_resp resp = {
		.via = MBX_DEV_VIA_PDO, .held = held, .pdo = at->pdo->nr, .cob_id = at->pdo->cob
	};
	devobj_answer(dl, &req->reply, 0, 0, &resp, sizeof resp);
}

void devobj_cmd_write(devobj_line *dl, const mbx_request *req)
{
	mbx_dev_obj_req o;
	uint16_t type;
	devobj_place at;
	memcpy(&o, req->payload, sizeof o);

	uint32_t abort = check_access(dl, &o, true, &type);
	uint16_t t = o.type ? o.type : type;
	uint32_t size = co_type_size((co_type)t);
	if (!abort && size && req->data_len != size)
		abort = req->data_len > size ? SDO_AB_LEN_HIGH : SDO_AB_LEN_LOW;
	if (abort)
		return devobj_answer(dl, &req->reply, MBX_E_ABORT, abort, NULL, 0);

	if (!(o.flags & MBX_DEV_SDO_ONLY) &&
	    devobj_find(dl, o.node, CO_PDO_RX, o.index, o.sub, &at) && at.rec >= 0)
		return by_pdo(dl, req, &o, &at);
	by_sdo(dl, req, &o, t, false);
}

/* The first complete frame for a device RPDO with a deadline: from now on
 * the daemon's TPDO repeats it at half the deadline, so that the device
 * does not miss it (its EMCY 8250h) between two writes. */
static void keep_sending(devobj_line *dl, const devobj_record *r)
{
	const co_pdo_layout_node *n = co_pdo_layout_node_get(line_pdo_layout(dl->l), r->node);
	uint16_t deadline = n ? n->pdo[CO_PDO_RX][r->dev_pos].event_ms : 0;
	if (deadline)
		devobj_mirror_keep_sending(&dl->mirror, r, deadline / 2u ? deadline / 2u : 1u);
}

void devobj_tx_send(devobj_line *dl, unsigned i, uint64_t now_us)
{
	co_node *co = line_node(dl->l);
	devobj_tx *tx = &dl->tx[i];
	const devobj_record *r = &dl->mirror.rec[CO_PDO_TX][i];
	co_od_entry *slot = co_od_find(co_node_od(co), DEVOBJ_SLOT_TX_INDEX, r->slot_sub);

	co_od_entry_set_raw(slot, co_get_le(tx->frame, 8));
	if (!tx->sent)
		keep_sending(dl, r); /* before: the transmission starts the timer */
	if (co_pdo_tpdo_event(co, r->nr, now_us) < 0)
		dl->tx_failed++; /* not OPERATIONAL: the value waits in the slot */
	if (tx->dirty)
		dl->n_dirty--;
	tx->dirty = false;
	tx->sent_us = now_us;
	tx->sent++;
}

/* Send the frames that are due: the slot takes the frame, the TPDO goes. */
uint64_t devobj_write_poll(devobj_line *dl, uint64_t now_us)
{
	uint64_t next = CO_NO_DEADLINE;
	for (unsigned i = 0; i < dl->mirror.n_rec[CO_PDO_TX] && dl->n_dirty; i++) {
		devobj_tx *tx = &dl->tx[i];
		const devobj_record *r = &dl->mirror.rec[CO_PDO_TX][i];
		if (!tx->dirty)
			continue;
		if (!r->busy) { /* released since: nothing to send */
			tx->dirty = false;
			dl->n_dirty--;
			continue;
		}
		if (now_us < tx->due_us) {
			if (tx->due_us < next)
				next = tx->due_us;
			continue;
		}
		devobj_tx_send(dl, i, now_us);
	}
	return next;
}
