/* SPDX-License-Identifier: MIT */
/*
 * lines/line_cmds.c - mailbox commands carried out on the line thread that
 * owns the core instance. The mailbox server has already validated the
 * envelope, the payload fields and the client's access; what is checked
 * here is what only the line knows (does the object exist, is the node id
 * ours, is a service available).
 *
 * Long operations (SDO, LSS, store) park the request in a pending slot and
 * answer from the completion event (line_events.c); nothing waits here.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/lss_master.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sdo_client.h"
#include "lines/log.h"

static void answer(line *l, const mbx_request *req, int status, uint32_t abort,
		   const void *payload, size_t len)
{
	mbx_server_respond(l->mbx, &req->reply, status, abort, payload, len);
}

/* ---- pending requests ----------------------------------------------------- */

static line_pending *pending_take(line *l, const mbx_request *req, bool big)
{
	int first = big ? 0 : LINE_BIG_SLOTS, last = big ? LINE_BIG_SLOTS : LINE_PENDING_MAX;
	/* The last entry of each kind is for writers: read-only clients
	 * parking uploads (a dead node answers nothing for the whole SDO
	 * timeout) must not make a writer's request fail with BUSY (issue
	 * 11; the mailbox limits how many requests readers park at all). */
	if (req->access < MBX_ACCESS_WRITE) {
		int used = 0;
		for (int i = first; i < last; i++)
			used += l->pending[i].used;
		if (used >= last - first - 1)
			return NULL;
	}
	for (int i = first; i < last; i++) {
		line_pending *pp = &l->pending[i];
		if (!pp->used) {
			pp->used = true;
			pp->code = req->code;
			pp->reply = req->reply;
			pp->tag = l->next_tag++;
			return pp;
		}
	}
	return NULL;
}

line_pending *line_pending_find(line *l, uint64_t tag)
{
	for (int i = 0; i < LINE_PENDING_MAX; i++)
		if (l->pending[i].used && l->pending[i].tag == tag)
			return &l->pending[i];
	return NULL;
}

void line_pending_release(line *l, line_pending *pp)
{
	(void)l;
	pp->used = false;
}

/* ---- local object dictionary ---------------------------------------------- */

static void od_read(line *l, const mbx_request *req, const mbx_obj_req *o)
{
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(co_node_od(l->node), o->index, o->sub, &abort);
	if (!e)
		return answer(l, req, MBX_E_ABORT, abort, NULL, 0);
	if (!(e->access & CO_ACC_READ))
		return answer(l, req, MBX_E_ABORT, 0x06010001u, NULL, 0);
	answer(l, req, 0, 0, e->data, e->size);
}

static void od_write(line *l, const mbx_request *req, const mbx_obj_req *o, bool trigger_pdo)
{
	uint32_t abort = 0;
	co_od_entry *e = co_od_find_ex(co_node_od(l->node), o->index, o->sub, &abort);
	if (!e)
		return answer(l, req, MBX_E_ABORT, abort, NULL, 0);
	if (!(e->access & CO_ACC_WRITE) || (e->access & CO_ACC_CONST))
		return answer(l, req, MBX_E_ABORT, 0x06010002u, NULL, 0);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL, .data = req->data, .size = (uint32_t)req->data_len };
	abort = co_od_write(e, req->data, (uint32_t)req->data_len, &a);
	if (abort == CO_OD_DEFERRED)
		abort = 0x08000021u; /* a local write cannot wait: "local control" */
	if (abort)
		return answer(l, req, MBX_E_ABORT, abort, NULL, 0);
	if (trigger_pdo)
		co_pdo_object_changed(l->node, o->index, o->sub, l->now_us);
	answer(l, req, 0, 0, NULL, 0);
}

/* ---- SDO client ----------------------------------------------------------- */

static void sdo_transfer(line *l, const mbx_request *req, const mbx_sdo_req *s, bool upload)
{
	uint8_t channels = sdo_client_channel_count(l->node);
	if (!channels)
		return answer(l, req, MBX_E_UNSUPPORTED, 0, NULL, 0);
	if (s->node == co_node_id(l->node))
		return answer(l, req, MBX_E_PARAM, 0, NULL, 0);
	/* A target always uses the same channel: its transfers queue in order
	 * there instead of colliding on the server's single channel. */
	uint8_t channel = (uint8_t)((s->node - 1u) % channels);
	bool big = upload ? (s->size == 0 || s->size > LINE_INLINE_MAX) : req->data_len > LINE_INLINE_MAX;
	line_pending *pp = pending_take(l, req, big);
	if (!pp && big && !upload)
		return answer(l, req, MBX_E_BUSY, 0, NULL, 0);
	if (!pp && big)
		pp = pending_take(l, req, false); /* small upload still possible */
	if (!pp)
		return answer(l, req, MBX_E_BUSY, 0, NULL, 0);

	/* timeout_ms 0 means "the line's default" (docs/mailbox.md): that is
	 * the configured lines[].sdo_timeout_ms, which cogwd hands over as the
	 * node's SDO timeout. Passing 0 on let the core use its own 1000 ms,
	 * so the configured value never reached mailbox SDO transfers. */
	uint32_t timeout_ms = s->timeout_ms ? s->timeout_ms : l->p.node.sdo_server_timeout_ms;
	sdo_client_req r = {
		.upload = upload, .node_id = s->node, .index = s->index, .sub = s->sub,
		.mode = s->mode, .timeout_ms = timeout_ms, .tag = pp->tag,
	};
	if (upload) {
		r.size = s->size;
		/* A small slot uploads into its inline buffer. Give it its
		 * capacity too: it used to keep pp->buf = inline_data with
		 * pp->cap = 0 after its first use, so the slot's next upload
		 * got a 0-byte buffer and aborted 05040005 (found with more
		 * uploads in flight than LINE_BIG_SLOTS). */
		if (!pp->buf) {
			pp->buf = pp->inline_data;
			pp->cap = LINE_INLINE_MAX;
		}
		r.buf = pp->buf;
		r.cap = pp->cap;
	} else {
		r.size = (uint32_t)req->data_len;
		if (req->data_len <= LINE_INLINE_MAX) {
			/* a single-message command's data lives only during dispatch */
			memcpy(pp->inline_data, req->data, req->data_len);
			r.data = pp->inline_data;
		} else {
			r.data = req->data; /* chunked: valid until answered */
		}
	}
	int rc = sdo_client_submit(l->node, channel, &r, l->now_us);
	if (rc < 0) {
		line_pending_release(l, pp);
		return answer(l, req, rc == -ENOSPC ? MBX_E_BUSY : MBX_E_PARAM, 0, NULL, 0);
	}
}

/* ---- NMT and nodes -------------------------------------------------------- */

static void nmt_cmd(line *l, const mbx_request *req, const mbx_nmt_req *n)
{
	/* Addressed to the daemon's own node-ID: the kernel does not loop our
	 * own frame back to us, so sent on the bus it would change nothing.
	 * Apply it locally instead (e.g. "start" makes the manager OPERATIONAL
	 * so that its RPDOs run and PDO events flow). A vetoed start is a
	 * state refusal. */
	if (n->node == co_node_id(l->node)) {
		int lrc = co_nmt_local_cmd(l->node, n->cs, l->now_us);
		return answer(l, req, lrc == 0 ? 0 : lrc == -EPERM ? MBX_E_STATE : MBX_E_PARAM, 0, NULL, 0);
	}
	int rc = co_nmt_master_send(l->node, n->node, n->cs, l->now_us);
	answer(l, req, rc < 0 ? MBX_E_PARAM : 0, 0, NULL, 0);
}

/* The heartbeat consumer is the source of truth for states and times; the
 * line adds what only it counts (boot-ups, EMCYs). */
static void node_table(line *l, const mbx_request *req)
{
	mbx_node_entry rows[LINE_NODES];
	size_t n = 0;
	for (int i = 1; i < LINE_NODES; i++) {
		const line_node_info *ni = &l->nodes[i];
		uint8_t state = co_hb_remote_state(l->node, (uint8_t)i);
		co_hb_mon mon = co_hb_consumer_status(l->node, (uint8_t)i);
		uint64_t heard = co_hb_last_heard_us(l->node, (uint8_t)i);
		if (state == CO_HB_STATE_UNKNOWN && mon == CO_HB_MON_OFF && !ni->emcy_count)
			continue;
		uint64_t ago_ms = heard ? (l->now_us - heard) / 1000u : UINT32_MAX;
		rows[n++] = (mbx_node_entry){
			.node = (uint8_t)i,
			.nmt_state = state,
			.hb = mon == CO_HB_MON_LOST ? 2 : mon == CO_HB_MON_ACTIVE ? 1 : mon == CO_HB_MON_WAITING ? 3 : 0,
			.flags = (uint8_t)((ni->bootups ? 1 : 0) | (ni->emcy_count && ni->last_emcy ? 2 : 0)),
			.last_heard_ms = ago_ms > UINT32_MAX ? UINT32_MAX : (uint32_t)ago_ms,
			.bootups = ni->bootups > UINT16_MAX ? UINT16_MAX : (uint16_t)ni->bootups,
			.last_emcy = ni->last_emcy,
			.emcy_count = ni->emcy_count,
		};
	}
	answer(l, req, 0, 0, rows, n * sizeof rows[0]);
}

static void line_status(line *l, const mbx_request *req)
{
	const can_port_stats *cs = can_port_get_stats(l->port);
	const co_node_stats *ns = co_node_get_stats(l->node);
	mbx_line_status st = {
		.can_state = line_mbx_can_state(can_port_bus_state(l->port)),
		.nmt_state = co_nmt_get_state(l->node),
		.node_id = co_node_id(l->node),
		.bitrate = l->p.can.bitrate,
		.rx_frames = cs->rx_frames,
		.tx_frames = cs->tx_frames,
		.rx_dropped = cs->rx_overflow_drops,
		.tx_failed = cs->tx_drops + cs->tx_errors + ns->tx_failed,
		.err_frames = cs->rx_error_frames,
		.bus_off_count = cs->bus_off_count,
		.clients = mbx_server_stats_get(l->mbx)->clients,
		.bus_load_permille = cs->bus_load_permille,
	};
	answer(l, req, 0, 0, &st, sizeof st);
}

/* ---- PDO, EMCY, raw ------------------------------------------------------- */

static void pdo_request(line *l, const mbx_request *req, const mbx_pdo_num_req *p)
{
	int rc = co_pdo_tpdo_event(l->node, p->pdo, l->now_us);
	answer(l, req, rc == 0 ? 0 : rc == -ENOENT ? MBX_E_PARAM : MBX_E_STATE, 0, NULL, 0);
}

static void emcy_send(line *l, const mbx_request *req, const mbx_emcy_req *e)
{
	int rc = e->code ? co_emcy_send(l->node, e->code, e->reg, e->msef, l->now_us)
			 : co_emcy_clear_all(l->node, l->now_us);
	answer(l, req, rc == 0 ? 0 : rc == -ENODEV ? MBX_E_UNSUPPORTED : MBX_E_STATE, 0, NULL, 0);
}

static void raw_send(line *l, const mbx_request *req)
{
	size_t n = req->fixed_len / sizeof(mbx_raw_frame);
	for (size_t i = 0; i < n; i++) {
		mbx_raw_frame rf;
		memcpy(&rf, req->payload + i * sizeof rf, sizeof rf);
		co_frame f;
		co_frame_init(&f, rf.id & ~(MBX_RAW_EXT | MBX_RAW_RTR), rf.len);
		if (rf.id & MBX_RAW_EXT)
			f.flags |= CO_FRAME_EXT;
		if (rf.id & MBX_RAW_RTR)
			f.flags |= CO_FRAME_RTR;
		else
			memcpy(f.data, rf.data, rf.len);
		if (co_node_send(l->node, &f) < 0)
			return answer(l, req, MBX_E_BUSY, 0, NULL, 0);
	}
	answer(l, req, 0, 0, NULL, 0);
}

/* ---- LSS master ----------------------------------------------------------- */

static lss_master_service lss_service_of(uint16_t code, uint8_t what)
{
	switch (code) {
	case MBX_CMD_LSS_SWITCH_GLOBAL: return LSS_SVC_SWITCH_GLOBAL;
	case MBX_CMD_LSS_SWITCH_SELECTIVE: return LSS_SVC_SWITCH_SELECTIVE;
	case MBX_CMD_LSS_SET_NODE_ID: return LSS_SVC_CONFIG_NODE_ID;
	case MBX_CMD_LSS_SET_BIT_TIMING: return LSS_SVC_CONFIG_BIT_TIMING;
	case MBX_CMD_LSS_ACTIVATE_BIT_TIMING: return LSS_SVC_ACTIVATE_BIT_TIMING;
	case MBX_CMD_LSS_STORE: return LSS_SVC_STORE;
	case MBX_CMD_LSS_IDENTIFY_REMOTE: return LSS_SVC_IDENTIFY_REMOTE;
	case MBX_CMD_LSS_IDENTIFY_NONCONF: return LSS_SVC_IDENTIFY_NON_CONFIGURED;
	case MBX_CMD_LSS_FASTSCAN: return LSS_SVC_FASTSCAN;
	case MBX_CMD_LSS_INQUIRE:
		switch (what) {
		case 0x5A: return LSS_SVC_INQUIRE_VENDOR;
		case 0x5B: return LSS_SVC_INQUIRE_PRODUCT;
		case 0x5C: return LSS_SVC_INQUIRE_REVISION;
		case 0x5D: return LSS_SVC_INQUIRE_SERIAL;
		case 0x5E: return LSS_SVC_INQUIRE_NODE_ID;
		}
		break;
	}
	return LSS_SVC_NONE;
}

static void lss_cmd(line *l, const mbx_request *req, const mbx_lss_req *q)
{
	lss_master_service svc = lss_service_of(req->code, q->what);
	if (svc == LSS_SVC_NONE)
		return answer(l, req, MBX_E_PARAM, 0, NULL, 0);
	line_pending *pp = pending_take(l, req, false);
	if (!pp)
		return answer(l, req, MBX_E_BUSY, 0, NULL, 0);
	lss_master_req r = {
		.service = svc, .tag = pp->tag, .timeout_ms = q->timeout_ms, .mode = q->mode,
		.node_id = q->node, .table = q->table, .index = q->bit_index, .delay_ms = q->delay_ms,
		.addr = { .id = { q->vendor, q->product, q->rev_lo, q->ser_lo } },
		.addr_high = { .id = { q->vendor, q->product, q->rev_hi, q->ser_hi } },
	};
	int rc = lss_master_submit(l->node, &r, l->now_us);
	if (rc < 0) {
		line_pending_release(l, pp);
		answer(l, req, rc == -ENODEV ? MBX_E_UNSUPPORTED : rc == -ENOSPC ? MBX_E_BUSY : MBX_E_PARAM,
		       0, NULL, 0);
	}
}

void line_lss_done(line *l, const co_ev_lss_master *m)
{
	line_pending *pp = line_pending_find(l, m->tag);
	if (!pp)
		return;
	mbx_lss_resp resp = {
		.error = m->error_code, .spec_error = m->error_spec,
		.found = m->result == LSS_RESULT_OK && m->answers > 0,
		.value = m->service == LSS_SVC_INQUIRE_NODE_ID ? m->node_id : m->value,
	};
	memcpy(resp.id, m->identity, sizeof resp.id);
	int status = 0;
	switch (m->result) {
	case LSS_RESULT_OK: break;
	case LSS_RESULT_SLAVE_ERROR: status = MBX_E_LSS; break;
	case LSS_RESULT_TIMEOUT: status = MBX_E_NO_ANSWER; break; /* the slave, not us */
	case LSS_RESULT_NOT_FOUND: status = MBX_E_NOT_FOUND; break;
	default: status = MBX_E_STATE; break;
	}
	mbx_server_respond(l->mbx, &pp->reply, status, 0, &resp, sizeof resp);
	line_pending_release(l, pp);
}

/* ---- dispatch ------------------------------------------------------------- */

void line_dispatch(void *ctx, mbx_server *srv, const mbx_request *req)
{
	line *l = ctx;
	(void)srv;
	const uint8_t *p = req->payload;
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->on_command && req->code >= x->ops->cmd_first &&
		    req->code <= x->ops->cmd_last && x->ops->cmd_last)
			return x->ops->on_command(x->ctx, l, req);
	}
	switch (req->code) {
	case MBX_CMD_OD_READ:
	case MBX_CMD_PDO_READ: {
		mbx_obj_req o;
		memcpy(&o, p, sizeof o);
		return od_read(l, req, &o);
	}
	case MBX_CMD_OD_WRITE:
	case MBX_CMD_PDO_WRITE: {
		mbx_obj_req o;
		memcpy(&o, p, sizeof o);
		return od_write(l, req, &o, req->code == MBX_CMD_PDO_WRITE && (o.flags & MBX_PDO_TRIGGER));
	}
	case MBX_CMD_SDO_UPLOAD:
	case MBX_CMD_SDO_DOWNLOAD: {
		mbx_sdo_req s;
		memcpy(&s, p, sizeof s);
		return sdo_transfer(l, req, &s, req->code == MBX_CMD_SDO_UPLOAD);
	}
	case MBX_CMD_NMT: {
		mbx_nmt_req n;
		memcpy(&n, p, sizeof n);
		return nmt_cmd(l, req, &n);
	}
	case MBX_CMD_NODE_TABLE:
		return node_table(l, req);
	case MBX_CMD_PDO_REQUEST: {
		mbx_pdo_num_req n;
		memcpy(&n, p, sizeof n);
		return pdo_request(l, req, &n);
	}
	case MBX_CMD_EMCY_SEND: {
		mbx_emcy_req e;
		memcpy(&e, p, sizeof e);
		return emcy_send(l, req, &e);
	}
	case MBX_CMD_RAW_SEND:
		return raw_send(l, req);
	case MBX_CMD_LINE_STATUS:
		return line_status(l, req);
	case MBX_CMD_STORE:
	case MBX_CMD_RESTORE: {
		mbx_store_req s;
		memcpy(&s, p, sizeof s);
		if (!l->state_path[0])
			return answer(l, req, MBX_E_UNSUPPORTED, 0, NULL, 0);
		int rc = line_store_request_mbx(l, req->code == MBX_CMD_STORE ? 1 : 2, s.sub, &req->reply);
		if (rc < 0)
			answer(l, req, rc == -EBUSY ? MBX_E_BUSY : MBX_E_PARAM, 0, NULL, 0);
		return;
	}
	default:
		if (req->code >= MBX_CMD_LSS_SWITCH_GLOBAL && req->code <= MBX_CMD_LSS_FASTSCAN) {
			mbx_lss_req q;
			memcpy(&q, p, sizeof q);
			return lss_cmd(l, req, &q);
		}
		return answer(l, req, MBX_E_UNSUPPORTED, 0, NULL, 0);
	}
}

void line_client_gone(void *ctx, mbx_server *srv, uint32_t client)
{
	line *l = ctx;
	(void)srv;
	/* Cancel the SDO transfers the client started: its answers could not be
	 * delivered, and the channel would stay busy for nothing. */
	for (int i = 0; i < LINE_PENDING_MAX; i++) {
		line_pending *pp = &l->pending[i];
		if (!pp->used || pp->reply.client != client)
			continue;
		if (pp->code == MBX_CMD_SDO_UPLOAD || pp->code == MBX_CMD_SDO_DOWNLOAD) {
			uint8_t channels = sdo_client_channel_count(l->node);
			for (uint8_t ch = 0; ch < channels; ch++)
				if (sdo_client_cancel(l->node, ch, pp->tag, 0x08000000u, l->now_us) == 0)
					break;
		}
		pp->used = false;
	}
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->on_client_gone)
			x->ops->on_client_gone(x->ctx, l, client);
	}
}
