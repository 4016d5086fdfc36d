/* SPDX-License-Identifier: MIT */
/*
 * lines/line_events.c - what the line's core and CAN port tell, turned into
 * mailbox events. Answers to requests are not here: each comes from the
 * confirmation of its own request (line_sdo.c, line_lss.c, line_store.c).
 * Runs on the line thread, inside the core's event callback: nothing here
 * blocks; a full client queue is the mailbox server's business (drop,
 * count, flag).
 */
#include "lines/line_internal.h"

#include <string.h>

#include "core/heartbeat.h"
#include "core/nmt.h"
#include "core/time.h"
#include "lines/log.h"

static void publish_node(line *l, uint16_t code, uint8_t node, uint8_t state, uint8_t prev)
{
	mbx_ev_node ev = { .node = node, .state = state, .prev = prev };
	mbx_server_publish(l->mbx, code, 0, &ev, sizeof ev);
}

/* Pull the bits of one mapped object out of a PDO payload (CiA 301: bit
 * offset counted from bit 0 of byte 0, little-endian). */
static uint8_t extract_bits(const uint8_t *data, unsigned bit_off, unsigned bits, uint8_t out[8])
{
	memset(out, 0, 8);
	if (bit_off % 8 == 0 && bits % 8 == 0) {
		memcpy(out, data + bit_off / 8, bits / 8);
	} else {
		for (unsigned b = 0; b < bits; b++) {
			unsigned src = bit_off + b;
			if (data[src / 8] & (1u << (src % 8)))
				out[b / 8] |= (uint8_t)(1u << (b % 8));
		}
	}
	return (uint8_t)((bits + 7) / 8);
}

static void publish_rpdo(line *l, const co_ev_pdo *p, uint64_t now)
{
	struct {
		mbx_ev_pdo head;
		mbx_pdo_value values[MBX_PDO_VALUES_MAX];
	} ev;
	memset(&ev, 0, sizeof ev);
	ev.head.ts_us = now;
	ev.head.pdo = p->nr;
	unsigned off = 0, n = 0;
	for (unsigned i = 0; i < p->n_map && n < MBX_PDO_VALUES_MAX; i++) {
		const co_ev_pdo_map *m = &p->map[i];
		if (off + m->bits > p->len * 8u)
			break;
		if (m->index > 0x0007) { /* dummy entries carry nothing */
			mbx_pdo_value *v = &ev.values[n++];
			v->index = m->index;
			v->sub = m->sub;
			v->len = extract_bits(p->data, off, m->bits, v->data);
		}
		off += m->bits;
	}
	ev.head.n = (uint8_t)n;
	mbx_server_publish(l->mbx, MBX_EV_PDO, 0, &ev, sizeof ev.head + n * sizeof ev.values[0]);
}

/* Error control of remote nodes: boot-ups, heartbeat and guarding. */
static void publish_errctrl(line *l, const co_event *ev)
{
	switch (ev->kind) {
	case CO_EV_BOOTUP:
		if (ev->u.errctrl.node < LINE_NODES)
			l->nodes[ev->u.errctrl.node].bootups++;
		publish_node(l, MBX_EV_BOOTUP, ev->u.errctrl.node, 0, ev->u.errctrl.prev);
		break;
	case CO_EV_HB_STARTED:
	case CO_EV_GUARD_RESUMED:
		publish_node(l, MBX_EV_HB_STARTED, ev->u.errctrl.node, ev->u.errctrl.state,
			     ev->u.errctrl.prev);
		break;
	case CO_EV_HB_LOST:
	case CO_EV_GUARD_FAILED:
		cogw_log(COGW_LOG_WARNING, "line %s: node %u %s lost (%u ms)", l->name,
			 ev->u.errctrl.node, ev->kind == CO_EV_HB_LOST ? "heartbeat" : "guarding",
			 ev->u.errctrl.time_ms);
		publish_node(l, MBX_EV_HB_LOST, ev->u.errctrl.node, ev->u.errctrl.state,
			     ev->u.errctrl.prev);
		break;
	case CO_EV_HB_STATE:
		publish_node(l, MBX_EV_NMT_STATE, ev->u.errctrl.node, ev->u.errctrl.state,
			     ev->u.errctrl.prev);
		break;
	case CO_EV_GUARD_LIFE_LOST:
		cogw_log(COGW_LOG_WARNING,
			 "line %s: our node is no longer guarded (life time %u ms)", l->name,
			 ev->u.errctrl.time_ms);
		/* fall through */
	case CO_EV_GUARD_TOGGLE:
	case CO_EV_GUARD_LIFE_RESUMED:
		publish_node(l,
			     ev->kind == CO_EV_GUARD_TOGGLE      ? MBX_EV_GUARD_TOGGLE
			     : ev->kind == CO_EV_GUARD_LIFE_LOST ? MBX_EV_LIFE_LOST
								 : MBX_EV_LIFE_RESUMED,
			     ev->u.errctrl.node, ev->u.errctrl.state, ev->u.errctrl.prev);
		break;
	default:
		break;
	}
}

/* Two answers to one SDO request of this line's client: two devices share
 * that node-ID (CiA 301 wants them unique). Every line notices it, with or
 * without a manager: counted per node (the node table), published to the
 * nmt class, logged the first time per node (the counter tells the rest). */
static void publish_duplicate(line *l, const co_ev_sdo_cli *c)
{
	line_node_info *ni;
	if (c->node_id < 1 || c->node_id >= LINE_NODES)
		return;
	ni = &l->nodes[c->node_id];
	if (!ni->duplicate_answers++)
		cogw_log(COGW_LOG_ERR,
			 "line %s: node %u: two answers to one SDO request (%04X:%02X): two "
			 "devices use node-ID %u",
			 l->name, c->node_id, c->index, c->sub, c->node_id);
	mbx_ev_dup_node e = { .node = c->node_id,
			      .sub = c->sub,
			      .index = c->index,
			      .count = ni->duplicate_answers,
			      .abort = c->abort };
	mbx_server_publish(l->mbx, MBX_EV_DUP_NODE, 0, &e, sizeof e);
}

/* SYNC can come every millisecond: the event is built only while some
 * client subscribed to the class (cached like the raw class's, see
 * line.c), so an unwatched SYNC costs one comparison. */
static void publish_sync(line *l, const co_event *ev)
{
	if (!l->sync_subscribers)
		return;
	mbx_ev_sync m = { .ts_us = ev->now_us,
			  .counter = ev->u.sync.counter,
			  .produced = ev->u.sync.produced };
	mbx_server_publish(l->mbx, MBX_EV_SYNC, 0, &m, sizeof m);
}

static void publish_time(line *l, const co_event *ev)
{
	co_time_of_day t = { .ms = ev->u.time.ms, .days = ev->u.time.days };
	mbx_ev_time m = { .ts_us = ev->now_us,
			  .unix_ms = co_time_to_unix_ms(&t),
			  .ms = t.ms,
			  .days = t.days,
			  .produced = ev->u.time.produced };
	mbx_server_publish(l->mbx, MBX_EV_TIME, 0, &m, sizeof m);
}

/* Extensions observe every event, after the line's own handling. */
static void tell_extensions(line *l, const co_event *ev)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->on_core_event)
			x->ops->on_core_event(x->ctx, l, ev);
	}
}

void line_on_core_event(void *ctx, const co_event *ev)
{
	line *l = ctx;
	uint64_t now = ev->now_us;
	line_app_on_core_event(l, ev); /* owned objects: transfers' ends, RPDO values */
	switch (ev->kind) {
	case CO_EV_OD_WRITTEN: {
		mbx_ev_od_written w = { .index = ev->u.od.index,
					.sub = ev->u.od.sub,
					.size = ev->u.od.size };
		mbx_server_publish(l->mbx, MBX_EV_OD_WRITTEN, 0, &w, sizeof w);
		break;
	}
	case CO_EV_NMT_STATE:
		cogw_log(COGW_LOG_INFO, "line %s: own NMT state %s -> %s", l->name,
			 co_nmt_state_to_string(ev->u.nmt.prev),
			 co_nmt_state_to_string(ev->u.nmt.state));
		publish_node(l, MBX_EV_NMT_STATE, co_node_id(l->node), ev->u.nmt.state,
			     ev->u.nmt.prev);
		line_appwd_on_nmt(l, &ev->u.nmt);
		break;
	case CO_EV_EMCY_RX: {
		const co_ev_emcy *e = &ev->u.emcy;
		if (e->node < LINE_NODES) {
			l->nodes[e->node].last_emcy = e->code;
			l->nodes[e->node].emcy_count++;
		}
		mbx_ev_emcy m = { .ts_us = now, .code = e->code, .node = e->node, .reg = e->reg };
		memcpy(m.msef, e->msef, sizeof m.msef);
		mbx_server_publish(l->mbx, MBX_EV_EMCY, 0, &m, sizeof m);
		break;
	}
	case CO_EV_RPDO:
		publish_rpdo(l, &ev->u.pdo, now);
		break;
	case CO_EV_RPDO_TIMEOUT:
	case CO_EV_RPDO_LENGTH:
	case CO_EV_RPDO_RECOVERED:
		line_publish_rpdo_fault(l, ev);
		break;
	case CO_EV_SYNC:
		publish_sync(l, ev);
		break;
	case CO_EV_TIME:
		publish_time(l, ev);
		break;
	case CO_EV_TX_FAILED:
		/* counted by the core and the port; the watermark log says more */
		break;
	case CO_EV_SDO_CLIENT_SECOND_ANSWER:
		publish_duplicate(l, &ev->u.sdo_cli);
		break;
	case CO_EV_COMM_FAULT:
		line_health_on_fault(l, &ev->u.commfault);
		break;
	default:
		/* boot-up, heartbeat, guarding; the core events no mailbox
		 * event carries are listed, with why, in docs/mailbox.md */
		publish_errctrl(l, ev);
		break;
	}
	/* a node outside the configuration (lines/line_scan.c) */
	line_unknown_on_event(l, ev);
	tell_extensions(l, ev);
}

void line_publish_raw(line *l, const co_frame *f, uint64_t ts_ns)
{
	mbx_ev_raw ev = { .ts_us = ts_ns / 1000u };
	ev.frame.id = f->id | ((f->flags & CO_FRAME_EXT) ? MBX_RAW_EXT : 0) |
		      ((f->flags & CO_FRAME_RTR) ? MBX_RAW_RTR : 0);
	ev.frame.len = f->len;
	memcpy(ev.frame.data, f->data, f->len);
	mbx_server_publish(l->mbx, MBX_EV_RAW, 0, &ev, sizeof ev);
}
