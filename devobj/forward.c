/* SPDX-License-Identifier: MIT */
/*
 * devobj/forward.c - PDO forwarding by device object (gateway.forward,
 * docs/gateway.md "Forwarding device objects").
 *
 * The source line takes the object's value out of the mirrored TPDO of its
 * device and writes it, as a 64-bit integer (sign-extended when the object
 * is signed), into the forward's process image object: the gateway hands
 * it to the other lines like any image update. The target line learns of
 * the update (CO_EV_OBJECT_UPDATED) and gives the value to the device's
 * RPDO the mirror produces - the frame leaves at once when every object of
 * that RPDO has a value, like a client's write by PDO but without the
 * update time: forwarding is not coalesced beyond what the image does (the
 * updates of one source frame come in one wake-up, docs/gateway.md).
 *
 * A device RPDO that carries the forwarded object alone needs nothing of
 * the target line but the value: its frame is the image object's low bits.
 * The TPDO that produces it names that object as its frame's source
 * (line_tpdo_sources), so the source line's thread sends the frame itself
 * in the wake-up the value came in (the gateway's fast path,
 * docs/gateway.md "One wake-up per hop"); the target line, when it applies
 * the value, triggers its TPDO at once and the gate tells the core that
 * frame already left. A device RPDO of several objects keeps the hand-off:
 * its objects come one by one at the source, and one frame must carry the
 * values of one source frame.
 */
#include <string.h>

#include "core/frame.h"
#include "core/od.h"
#include "devobj/devobj_int.h"
#include "devobj/value.h"
#include "lines/log.h"

static uint64_t low_bits(unsigned bits)
{
	return bits >= 64u ? UINT64_MAX : ((uint64_t)1 << bits) - 1u;
}

/* The entry's bits in the frame as a 64-bit integer of its type. */
static uint64_t entry_value(const uint8_t frame[8], const co_pdo_layout_entry *e)
{
	uint64_t v = (co_get_le(frame, 8) >> e->offset) & low_bits(e->bits);
	if (co_type_is_signed((co_type)e->type) && e->bits < 64u && (v >> (e->bits - 1u)) & 1u)
		v |= ~low_bits(e->bits); /* CiA 301 §7.1.5 */
	return v;
}

/* Whether the integer v keeps its value in the entry's bits. */
static bool entry_holds(const co_pdo_layout_entry *e, uint64_t v)
{
	if (e->bits >= 64u)
		return true;
	if (co_type_is_signed((co_type)e->type)) {
		int64_t s = (int64_t)v, lim = (int64_t)1 << (e->bits - 1u);
		return s >= -lim && s < lim;
	}
	return (v & ~low_bits(e->bits)) == 0;
}

void devobj_forward_received(devobj_line *dl, unsigned rec, uint64_t now_us)
{
	(void)now_us;
	co_od *od = co_node_od(line_node(dl->l));
	const devobj_rx *rx = &dl->rx[rec];
	for (unsigned i = 0; i < dl->p.n_fwd; i++) {
		const devobj_forward *f = &dl->p.fwd[i];
		devobj_place at;
		if (!f->source || f->node != rx->node ||
		    !devobj_find(dl, f->node, CO_PDO_TX, f->index, f->sub, &at) ||
		    at.rec != (int)rec)
			continue;
		co_od_entry *e = co_od_find(od, f->image, 0);
		uint8_t bytes[8];
		co_put_le(bytes, 8, entry_value(rx->frame, at.entry));
		/* through the hooks: the gateway publishes it (gateway/gw_pdo.c) */
		co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL, .data = bytes, .size = 8 };
		if (e && co_od_write(e, bytes, 8, &a) == 0)
			dl->fwd[i].values++;
		else
			dl->fwd[i].refused++;
	}
}

void devobj_forward_updated(devobj_line *dl, uint16_t index, uint8_t sub)
{
	if (sub != 0)
		return;
	co_od *od = co_node_od(line_node(dl->l));
	for (unsigned i = 0; i < dl->p.n_fwd; i++) {
		const devobj_forward *f = &dl->p.fwd[i];
		devobj_fwd_counters *c = &dl->fwd[i];
		devobj_place at;
		if (f->source || f->image != index)
			continue;
		const co_od_entry *e = co_od_find(od, f->image, 0);
		if (!e)
			continue;
		c->values++;
		uint64_t v = co_od_entry_raw(e);
		if (!devobj_find(dl, f->node, CO_PDO_RX, f->index, f->sub, &at) || at.rec < 0 ||
		    !entry_holds(at.entry, v)) {
			c->refused++;
			continue;
		}
		devobj_tx *tx = &dl->tx[at.rec];
		uint64_t mask = low_bits(at.entry->bits);
		uint64_t frame = co_get_le(tx->frame, 8);
		frame = (frame & ~(mask << at.entry->offset)) | ((v & mask) << at.entry->offset);
		co_put_le(tx->frame, 8, frame);
		if (tx->dirty)
			c->superseded++;
		/* alone in its frame: at once, while the gate knows whether the
		 * source line sent it (the update is being applied) */
		if (!devobj_tx_given(dl, &at, true) && at.pdo->n == 1)
			devobj_tx_send(dl, (unsigned)at.rec, line_loop_now_us(dl->l));
	}
}

void devobj_forward_sources(devobj_line *dl)
{
	line_tpdo_source src[DEVOBJ_FORWARDS_MAX];
	uint16_t nr[DEVOBJ_FORWARDS_MAX];
	unsigned n = 0;

	for (unsigned i = 0; i < dl->p.n_fwd; i++) {
		const devobj_forward *f = &dl->p.fwd[i];
		devobj_place at;
		if (f->source || !devobj_find(dl, f->node, CO_PDO_RX, f->index, f->sub, &at) ||
		    at.rec < 0 || at.pdo->n != 1)
			continue;
		nr[n] = dl->mirror.rec[CO_PDO_TX][at.rec].nr;
		src[n++] = (line_tpdo_source){ .index = f->image,
					       .sub = 0,
					       .bits = at.entry->bits,
					       .is_signed = co_type_is_signed(
						       (co_type)at.entry->type) };
	}
	/* every record named afresh: those that no longer carry a forward alone
	 * lose their sources */
	for (unsigned i = 0; i < dl->mirror.n_rec[CO_PDO_TX]; i++) {
		uint16_t rec_nr = dl->mirror.rec[CO_PDO_TX][i].nr;
		unsigned k = 0;
		while (k < n && nr[k] != rec_nr)
			k++;
		if (line_tpdo_sources_set(dl->l, rec_nr, k < n ? &src[k] : NULL, k < n ? 1 : 0) < 0)
			cogw_log(COGW_LOG_WARNING,
				 "line %s: PDO %u of the device object forwards keeps the hand-off "
				 "(no room to name its source)",
				 dl->p.name, rec_nr);
	}
}

/* The frames a target's device RPDO sent since the last look: the record's
 * count is shared by the objects it carries. */
static uint32_t sent_of(const devobj_line *dl, const devobj_forward *f)
{
	devobj_place at;
	if (f->source || !devobj_find(dl, f->node, CO_PDO_RX, f->index, f->sub, &at) || at.rec < 0)
		return 0;
	return dl->tx[at.rec].sent;
}

void devobj_cmd_forwards(devobj_line *dl, const mbx_request *req)
{
	mbx_dev_forward out[DEVOBJ_FORWARDS_MAX];
	for (unsigned i = 0; i < dl->p.n_fwd; i++) {
		const devobj_forward *f = &dl->p.fwd[i];
		const devobj_fwd_counters *c = &dl->fwd[i];
		out[i] = (mbx_dev_forward){ .source = f->source,
					    .node = f->node,
					    .sub = f->sub,
					    .index = f->index,
					    .image = f->image,
					    .peer_line = f->peer_line,
					    .peer_node = f->peer_node,
					    .peer_sub = f->peer_sub,
					    .peer_index = f->peer_index,
					    .values = c->values,
					    .sent = sent_of(dl, f),
					    .superseded = c->superseded,
					    .refused = c->refused };
	}
	devobj_answer(dl, &req->reply, 0, 0, out, dl->p.n_fwd * sizeof out[0]);
}
