/* SPDX-License-Identifier: MIT */
/*
 * gateway/gateway.c - the gateway as a line extension (gateway.h).
 *
 * A routed SDO transfer touches two lines: the entry line owns the session
 * (its SDO server channel, the state machine, the timers) and the target
 * line owns a relay lease (one SDO client channel of its pool, toward the
 * target node or the next router). They exchange fixed-size messages over
 * the rings: OPEN/OPENED, frames both ways, CLOSE. A lease whose session
 * vanished (its CLOSE lost to a full ring) is given back after an idle
 * limit, so every channel is released whatever happens.
 */
#include "gateway/gateway.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/heartbeat.h"
#include "core/pdo.h"
#include "core/sdo_client.h"
#include "core/sdo_server.h"
#include "gateway/convention.h"
#include "gateway/image.h"
#include "gateway/pdo_sync.h"
#include "gateway/route.h"
#include "gateway/sdo_route.h"
#include "lines/line.h"
#include "mailbox/proto.h"
#include "mailbox/server.h"
#include "lines/xring.h"

#define GW_RELAYS_MAX 128u
#define GW_RING_SLOTS 1024u
#define GW_RELAY_IDLE_FACTOR 8u  /* idle lease given back after 8 timeouts */
#define GW_REBUILD_US 1000000u   /* forwarding list re-checked every 1 s */
#define GW_LINK_CHECK_US 100000u /* link of a line holding leases: every 100 ms */

enum gw_msg_kind {
	M_FWD = 1,   /* a B-object changed: slot, its new value in bits */
	M_EMCY,      /* send a forwarded EMCY: net, src_node, code */
	M_OPEN,      /* lease a client toward node for session sid */
	M_OPENED,    /* the answer: abort */
	M_TO_TARGET, /* a requester frame: d */
	M_TO_REQ,    /* a target frame: d */
	M_CLOSE,     /* give the lease of sid back */
	M_LOST,      /* the target line carries no frames (link down, bus-off): sid ends */
	M_JOB,       /* run a mailbox SDO job (job) */
	M_JOB_DONE,  /* its outcome (job->abort, job->size) */
};

typedef struct gw_msg {
	uint8_t kind;
	uint8_t from; /* sending line */
	uint8_t node; /* M_OPEN: target or router; M_EMCY: source node */
	uint8_t pad;
	uint32_t sid;       /* session: line << 24 | channel << 16 | generation */
	uint32_t abort;     /* M_OPENED, M_LOST */
	uint16_t slot;      /* M_FWD */
	uint16_t net;       /* M_EMCY: source network */
	uint16_t code;      /* M_EMCY: original error code */
	uint64_t bits;      /* M_FWD: the value written (gw_image_bits_from) */
	uint8_t d[8];       /* frames */
	struct gw_job *job; /* M_JOB, M_JOB_DONE: owned by the receiver meanwhile */
} gw_msg;

struct gw_line;

struct gw_sess {
	struct gw_line *gl;
	uint8_t ch;
	uint16_t gen;
	uint16_t net; /* the requested network (for the counters) */
	uint8_t target_line;
	uint64_t started_us; /* the network indication (for the listing) */
	gw_sdo_route r;
};

struct gw_relay {
	bool used;
	/* The line stopped carrying frames under it (link down, bus-off):
	 * the session was told and is gone, the device may still be in the
	 * transfer. Kept (the channel not lent again) until the line carries
	 * frames again, then the device gets an abort; or freed by the idle
	 * limit. */
	bool orphaned;
	uint8_t from;
	bool engaged;   /* the device got a frame of the transfer */
	uint8_t mux[3]; /* its index, sub-index (from that first frame) */
	int cli_ch;
	uint32_t sid;
	uint64_t last_us;
	struct gw_line *gl;
};

/* A mailbox SDO with a node of another network. Owned by the line whose
 * client asked (origin) except while in flight: M_JOB hands it to the
 * line that runs the transfer, M_JOB_DONE hands it back. */
enum job_phase {
	JOB_FREE,
	JOB_SENT,
	JOB_HOP,
	JOB_SDO
};

struct gw_job {
	uint8_t phase;
	uint8_t origin; /* line whose client waits */
	uint8_t runner; /* line that runs the transfer */
	bool upload;
	mbx_reply_to reply;
	gw_hop hop;
	uint16_t net;
	mbx_sdo_req sdo;
	const uint8_t *data; /* download: copied into buf */
	uint32_t len;
	uint8_t *buf; /* upload: max_transfer bytes, allocated at attach */
	uint32_t cap;
	int lease_ch;         /* JOB_HOP */
	uint64_t deadline_us; /* JOB_HOP */
	uint32_t abort;       /* outcome */
	uint32_t size;
	struct gw_line *gl_runner;
};

#define GW_JOBS 4u /* routed mailbox SDO requests per line at once */
#define GW_RUNNING_MAX 64u

struct gw_line {
	gw *g;
	unsigned idx;
	line *l;
	co_node *node;
	gw_line_params p;
	gw_route_table routes;
	gw_fwd_list fwd;
	gw_pdo_sync lost; /* updates that could not be handed to this line */
	bool fwd_dirty;
	uint64_t next_rebuild_us;
	uint64_t next_link_check_us;
	bool carried; /* what the last link check saw (relays_check_link) */
	struct gw_sess *sess;
	uint8_t n_sess;
	struct gw_relay relay[GW_RELAYS_MAX];
	struct gw_job jobs[GW_JOBS];            /* this line's clients' requests */
	struct gw_job *running[GW_RUNNING_MAX]; /* jobs this line runs now */
	gw_line_counters c;                     /* written by this line, read relaxed elsewhere */
};

struct gw {
	unsigned n;
	uint32_t max_transfer;
	gw_image *img;
	xring_mesh *mesh;
	struct gw_line line[GW_LINES_MAX];
};

#define COUNT(x) __atomic_fetch_add(&(x), 1, __ATOMIC_RELAXED)

/* ---- hand-off --------------------------------------------------------------------- */

static int send_to(struct gw_line *gl, unsigned to, gw_msg *m)
{
	xring *r = xring_mesh_get(gl->g->mesh, gl->idx, to);

	m->from = (uint8_t)gl->idx;
	return r ? xring_push(r, m, sizeof(*m)) : -EINVAL;
}

static uint32_t sid_of(const struct gw_sess *s)
{
	return (uint32_t)s->gl->idx << 24 | (uint32_t)s->ch << 16 | s->gen;
}

static struct gw_sess *sess_by_sid(struct gw_line *gl, uint32_t sid)
{
	uint8_t ch = (uint8_t)(sid >> 16);

	if ((sid >> 24) != gl->idx || ch >= gl->n_sess || gl->sess[ch].gen != (uint16_t)sid)
		return NULL;
	return &gl->sess[ch];
}

/* ---- routed sessions: the entry line ------------------------------------------------ */

static void s_to_requester(void *ctx, const uint8_t d[8])
{
	struct gw_sess *s = ctx;

	sdo_server_route_send(s->gl->node, s->ch, d);
}

static void s_to_target(void *ctx, const uint8_t d[8])
{
	struct gw_sess *s = ctx;
	gw_msg m = { .kind = M_TO_TARGET, .sid = sid_of(s) };

	memcpy(m.d, d, 8);
	if (send_to(s->gl, s->target_line, &m))
		COUNT(s->gl->c.ring_drops); /* the session's timeout ends it */
}

static uint32_t s_open(void *ctx, const gw_hop *hop)
{
	struct gw_sess *s = ctx;
	gw_msg m = { .kind = M_OPEN, .sid = sid_of(s), .node = hop->node };

	s->target_line = hop->line;
	if (send_to(s->gl, hop->line, &m)) {
		COUNT(s->gl->c.ring_drops);
		return GW_AB_ROUTE_BUSY;
	}
	return 0;
}

static void s_close(void *ctx)
{
	struct gw_sess *s = ctx;
	gw_msg m = { .kind = M_CLOSE, .sid = sid_of(s) };

	if (send_to(s->gl, s->target_line, &m))
		COUNT(s->gl->c.ring_drops); /* the relay's idle limit frees it */
}

static void s_done(void *ctx, uint32_t abort, gw_route_outcome o)
{
	struct gw_sess *s = ctx;
	struct gw_line *gl = s->gl;

	mbx_ev_gw_sdo ev = {
		.net = s->net,
		.node = s->r.target.node,
		.outcome = (uint8_t)o,
		.abort = abort,
		.target_line = s->r.opened || s->r.frames_to_target ? s->target_line : 0xFF,
		.router = s->r.hop.via_router ? s->r.hop.node : 0,
		.channel = s->ch,
		.frames = (uint32_t)(s->r.frames_to_target + s->r.frames_to_requester),
	};

	if (o == GW_OUT_REFUSED && !s->r.frames_to_target)
		ev.target_line = 0xFF;
	gw_route_count(&gl->routes, s->net, o);
	mbx_server_publish(line_mbx(gl->l), MBX_EV_GW_SDO, 0, &ev, sizeof ev);
	switch (o) {
	case GW_OUT_ROUTED:
		COUNT(gl->c.routed);
		break;
	case GW_OUT_ABORTED:
		COUNT(gl->c.aborted);
		break;
	case GW_OUT_TIMED_OUT:
		COUNT(gl->c.timed_out);
		break;
	default:
		COUNT(gl->c.refused);
		break;
	}
	sdo_server_route_end(gl->node, s->ch);
}

static const gw_sdo_route_ops sess_ops = {
	.to_requester = s_to_requester,
	.to_target = s_to_target,
	.open = s_open,
	.close = s_close,
	.done = s_done,
};

static uint32_t on_indication(void *ctx, uint8_t ch, const uint8_t d[8], uint64_t now_us)
{
	struct gw_line *gl = ctx;
	struct gw_sess *s;
	gw_netind ni;
	gw_hop hop = { 0 };
	uint32_t refuse;
	uint32_t target_ms = gl->p.sdo_timeout_ms;

	if (ch >= gl->n_sess)
		return GW_AB_ROUTE_BUSY;
	s = &gl->sess[ch];
	if (gw_sdo_route_busy(&s->r))
		return GW_AB_ROUTE_BUSY;
	COUNT(gl->c.sessions);
	refuse = gw_netind_decode(d, &ni);
	if (!refuse)
		refuse = gw_route_resolve(&gl->routes, ni.net, ni.node, (int)gl->idx, &hop);
	/* A router answers only after its own target did: give it time for
	 * its own per-frame timeout first. */
	if (hop.via_router)
		target_ms *= 2;
	s->gen++;
	s->net = ni.net;
	s->started_us = now_us;
	gw_sdo_route_start(&s->r, ni, refuse, &hop, gl->p.sdo_timeout_ms, target_ms, now_us);
	return 0;
}

static void on_route_frame(void *ctx, uint8_t ch, const uint8_t d[8], uint64_t now_us)
{
	struct gw_line *gl = ctx;

	if (ch < gl->n_sess)
		gw_sdo_route_requester_frame(&gl->sess[ch].r, d, now_us);
}

static void on_route_ended(void *ctx, uint8_t ch)
{
	struct gw_line *gl = ctx;

	if (ch < gl->n_sess)
		gw_sdo_route_cancel(&gl->sess[ch].r, SDO_AB_GENERAL, line_loop_now_us(gl->l));
}

static const sdo_server_route_ops server_hook = {
	.indication = on_indication,
	.frame = on_route_frame,
	.ended = on_route_ended,
};

/* ---- relay leases: the target line --------------------------------------------------- */

static void relay_free(struct gw_relay *r, uint64_t now_us)
{
	if (!r->used)
		return;
	sdo_client_lease_end(r->gl->node, (uint8_t)r->cli_ch, now_us);
	r->used = false;
	r->orphaned = false;
}

static void relay_rx(void *arg, const uint8_t d[8], uint64_t now_us)
{
	struct gw_relay *r = arg;
	gw_msg m = { .kind = M_TO_REQ, .sid = r->sid };

	r->last_us = now_us;
	memcpy(m.d, d, 8);
	COUNT(r->gl->c.relayed_frames);
	if (send_to(r->gl, r->from, &m))
		COUNT(r->gl->c.ring_drops);
}

/* This line's link went down: tell each requester's line, so that its
 * session ends now with `abort`; the leases stay, orphaned, until the
 * device can be told as well (relays_link_back). */
static void relays_link_lost(struct gw_line *gl, uint32_t abort)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++) {
		struct gw_relay *r = &gl->relay[i];
		gw_msg m = { .kind = M_LOST, .sid = r->sid, .abort = abort };

		if (!r->used || r->orphaned)
			continue;
		if (send_to(gl, r->from, &m))
			COUNT(gl->c.ring_drops); /* the requester's timeout ends it */
		r->orphaned = true;
	}
}

/* The link is back: a device left in the middle of an orphaned transfer
 * gets an abort (else it would refuse the next request toward it until
 * its own timeout, if it has one), and the channel is free again. */
static void relays_link_back(struct gw_line *gl, uint64_t now_us)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++) {
		struct gw_relay *r = &gl->relay[i];
		uint8_t d[8];

		if (!r->used || !r->orphaned)
			continue;
		if (r->engaged) {
			gw_sdo_abort_encode(d, r->mux, SDO_AB_GENERAL);
			sdo_client_lease_send(gl->node, (uint8_t)r->cli_ch, d);
		}
		relay_free(r, now_us);
	}
}

/* Can this line carry frames now? Each look that sees a change from the
 * last one ends the leases it cut off, or frees them once it carries
 * again - whichever look saw it (the periodic check or a lease request). */
static bool link_look(struct gw_line *gl, uint64_t now_us)
{
	bool carries = line_can_carry(gl->l);

	if (carries != gl->carried) {
		gl->carried = carries;
		if (carries)
			relays_link_back(gl, now_us);
		else
			relays_link_lost(gl, GW_AB_NO_ANSWER);
	}
	return carries;
}

/* A lease toward a line whose interface went down (ip link set down,
 * carrier lost) or bus-off would otherwise end only by the requester's
 * per-frame timeout: while leases are held (the caller knows), look at
 * the line every GW_LINK_CHECK_US. */
static void relays_check_link(struct gw_line *gl, uint64_t now_us, uint64_t *next)
{
	if (now_us >= gl->next_link_check_us) {
		gl->next_link_check_us = now_us + GW_LINK_CHECK_US;
		link_look(gl, now_us);
	}
	if (gl->next_link_check_us < *next)
		*next = gl->next_link_check_us;
}

static struct gw_relay *relay_by_sid(struct gw_line *gl, uint8_t from, uint32_t sid)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		if (gl->relay[i].used && !gl->relay[i].orphaned && gl->relay[i].from == from &&
		    gl->relay[i].sid == sid)
			return &gl->relay[i];
	return NULL;
}

/* Can this line serve a lease toward node now? 0 or the refusal. */
static uint32_t relay_check(struct gw_line *gl, uint8_t node, uint64_t now_us)
{
	if (!link_look(gl, now_us))
		return GW_AB_NO_ANSWER;
	if (co_hb_consumer_status(gl->node, node) == CO_HB_MON_LOST)
		return GW_AB_NO_ANSWER; /* known silent: refuse now, not by a timeout */
	return 0;
}

static void relay_open(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	gw_msg ans = { .kind = M_OPENED, .sid = m->sid };
	struct gw_relay *r = NULL;
	int ch;

	ans.abort = relay_check(gl, m->node, now_us);
	for (unsigned i = 0; !ans.abort && i < GW_RELAYS_MAX && !r; i++)
		if (!gl->relay[i].used)
			r = &gl->relay[i];
	if (!ans.abort && !r)
		ans.abort = GW_AB_NO_CLIENT;
	if (!ans.abort) {
		ch = sdo_client_lease(gl->node, m->node, 0, 0, relay_rx, r, now_us);
		if (ch >= 0) {
			r->used = true;
			r->orphaned = false;
			r->from = m->from;
			r->sid = m->sid;
			r->cli_ch = ch;
			r->engaged = false;
			r->last_us = now_us;
		} else {
			ans.abort = ch == -EALREADY ? GW_AB_ROUTE_BUSY : GW_AB_NO_CLIENT;
		}
	}
	if (send_to(gl, m->from, &ans)) {
		COUNT(gl->c.ring_drops);
		if (r && r->used)
			relay_free(r, now_us);
	}
}

/* ---- EMCY routing ---------------------------------------------------------------------- */

static void emcy_consumed(struct gw_line *gl, const co_ev_emcy *e)
{
	uint32_t bits = 0;
	gw_emcy_plan plan;
	gw_msg m = { .kind = M_EMCY, .net = gl->p.network_id, .node = e->node, .code = e->code };

	if (co_od_get_u32(co_node_od(gl->node), GW_OBJ_EMCY_ROUTES, e->node, &bits) || !bits)
		return;
	COUNT(gl->c.emcy.consumed);
	/* An EMCY another router forwarded keeps its origin (bytes 3..7). */
	if (e->code == GW_EMCY_FWD_CODE) {
		m.net = co_get_le16(&e->msef[0]);
		m.node = e->msef[2];
		m.code = co_get_le16(&e->msef[3]);
	}
	gw_emcy_route_plan(&gl->routes, bits, &plan);
	__atomic_fetch_add(&gl->c.emcy.unroutable, plan.unknown + plan.loops, __ATOMIC_RELAXED);
	mbx_ev_gw_emcy ev = { .src_net = m.net, .src_node = m.node, .code = m.code };
	for (unsigned j = 0; j < gl->g->n; j++) {
		if (!(plan.lines & (1u << j)) || gl->g->line[j].p.network_id == m.net)
			continue; /* never back into the network it came from */
		if (send_to(gl, j, &m)) {
			COUNT(gl->c.emcy.dropped);
		} else {
			COUNT(gl->c.emcy.forwarded);
			ev.lines |= (uint16_t)(1u << j);
		}
	}
	if (ev.lines)
		mbx_server_publish(line_mbx(gl->l), MBX_EV_GW_EMCY, 0, &ev, sizeof ev);
}

static void emcy_send(struct gw_line *gl, const gw_msg *m)
{
	co_od *od = co_node_od(gl->node);
	gw_emcy_fwd fwd = { .src_net = m->net, .src_node = m->node, .code = m->code };
	uint32_t cob;
	co_frame f;

	/* Our own EMCY COB-ID on this line (1014h), outside our 1003h. */
	if (co_od_get_u32(od, 0x1014, 0, &cob) || (cob & 0x80000000u)) {
		COUNT(gl->c.emcy.dropped);
		return;
	}
	co_od_get_u8(od, 0x1001, 0, &fwd.err_reg);
	co_frame_init(&f, cob & CO_FRAME_EFF_MASK, 8);
	if (cob & 0x20000000u)
		f.flags |= CO_FRAME_EXT;
	gw_emcy_fwd_encode(f.data, &fwd);
	if (co_node_send(gl->node, &f) == 0)
		COUNT(gl->c.emcy.sent);
}

/* ---- PDO forwarding ---------------------------------------------------------------------- */

/* A B-object of this line's OD was written - by an RPDO, over SDO or by a
 * mailbox client (its after_write hook): into the shared image, and to
 * every other line whose TPDOs map it. */
static void image_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct gw_line *gl = ctx;
	gw *g = gl->g;
	int slot;
	gw_msg m = { .kind = M_FWD };

	if (a->origin == CO_OD_ORIGIN_RESET)
		return; /* defaults restored on this line only */
	slot = gw_image_find(g->img, e->index, e->sub);
	if (slot < 0)
		return;
	m.bits = gw_image_bits_from(e->data, (uint8_t)e->size);
	gw_image_write(g->img, slot, m.bits);
	COUNT(gl->c.pdo_published);
	m.slot = (uint16_t)slot;
	for (unsigned j = 0; j < g->n; j++) {
		if (j == gl->idx || !gw_fwd_list_has(&g->line[j].fwd, slot))
			continue;
		if (send_to(gl, j, &m)) {
			COUNT(gl->c.pdo_dropped);
			gw_pdo_sync_mark(&g->line[j].lost, slot);
		} else {
			COUNT(gl->c.pdo_forwarded);
		}
	}
}

static const co_od_hooks image_hooks = {
	.after_write = image_written,
};

/* only_if_changed: a resync, which must not trigger a TPDO for a value
 * this line already holds. Returns whether the value was stored. */
static bool pdo_apply(struct gw_line *gl, int slot, uint64_t bits, bool only_if_changed,
		      uint64_t now_us)
{
	const gw_image_slot *s = gw_image_slot_at(gl->g->img, slot);
	uint8_t buf[8];
	co_od_entry *e;

	if (!s || !(e = co_od_find(co_node_od(gl->node), s->index, s->sub)))
		return false;
	gw_image_bits_to(bits, buf, s->size);
	if (only_if_changed && e->size == s->size && memcmp(e->data, buf, s->size) == 0)
		return false;
	/* The store runs no hook: the update does not come back as ours. */
	if (co_od_entry_set_bytes(e, buf, s->size))
		return false;
	COUNT(gl->c.pdo_applied);
	if (co_pdo_object_changed(gl->node, s->index, s->sub, now_us) > 0)
		COUNT(gl->c.pdo_triggered);
	return true;
}

/* An update from another line, in the order its source wrote them. */
static void pdo_fwd_received(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	pdo_apply(gl, m->slot, m->bits, false, now_us);
	gw_pdo_sync_received(&gl->lost, gl->g->img, m->slot, m->bits);
}

/* gw_pdo_sync_apply_fn: a resync, which must not trigger a TPDO for a
 * value this line already holds. */
static bool pdo_resync_apply(void *ctx, int slot, uint64_t bits)
{
	struct gw_line *gl = ctx;

	return pdo_apply(gl, slot, bits, true, line_loop_now_us(gl->l));
}

/* ---- mailbox: routed SDO for clients ------------------------------------------------ */

static void job_finish(struct gw_line *runner, struct gw_job *j, uint32_t abort, uint32_t size);

static void job_respond(struct gw_line *gl, struct gw_job *j)
{
	mbx_server *srv = line_mbx(gl->l);

	if (j->abort)
		mbx_server_respond(srv, &j->reply, MBX_E_ABORT, j->abort, NULL, 0);
	else
		mbx_server_respond(srv, &j->reply, 0, 0, j->upload ? j->buf : NULL,
				   j->upload ? j->size : 0);
	j->phase = JOB_FREE;
}

static void job_con(void *arg, const co_ev_sdo_cli *con)
{
	struct gw_job *j = arg;

	job_finish(j->gl_runner, j, con->abort, con->size);
}

/* Start the SDO transfer itself (toward the target, or the router that
 * has just confirmed the indication and now waits for the initiate). */
static void job_sdo(struct gw_line *gl, struct gw_job *j, bool no_wait, uint64_t now_us)
{
	sdo_client_req r = {
		.upload = j->upload,
		.node_id = j->hop.node,
		.index = j->sdo.index,
		.sub = j->sdo.sub,
		.mode = j->sdo.mode,
		.timeout_ms = j->sdo.timeout_ms,
		.con = job_con,
		.con_arg = j,
		.no_wait = no_wait,
	};
	int rc;

	if (j->upload) {
		r.buf = j->buf;
		r.cap = j->cap;
		r.size = j->sdo.size;
	} else {
		r.data = j->data;
		r.size = j->len;
	}
	j->phase = JOB_SDO;
	rc = sdo_client_pool_submit(gl->node, &r, now_us);
	if (rc)
		job_finish(gl, j, rc == -EBUSY ? GW_AB_NO_CLIENT : SDO_AB_GENERAL, 0);
}

static void job_lease_rx(void *arg, const uint8_t d[8], uint64_t now_us)
{
	struct gw_job *j = arg;
	struct gw_line *gl = j->gl_runner;

	if (j->phase != JOB_HOP)
		return;
	sdo_client_lease_end(gl->node, (uint8_t)j->lease_ch, now_us);
	if ((d[0] >> 5) == SDO_CCS_ABORT) {
		job_finish(gl, j, co_get_le32(&d[4]), 0);
		return;
	}
	if (d[0] != GW_NETIND_CS || co_get_le16(&d[1]) != j->net || d[3] != j->sdo.node) {
		job_finish(gl, j, SDO_AB_CMD, 0);
		return;
	}
	/* The router waits for the initiate on the server channel that has
	 * just confirmed: the channel we gave back starts it at once. */
	job_sdo(gl, j, true, now_us);
}

static void job_run(struct gw_line *gl, struct gw_job *j, uint64_t now_us)
{
	uint8_t d[8];
	uint32_t ab = relay_check(gl, j->hop.node, now_us);
	int ch;
	unsigned k;

	j->gl_runner = gl;
	for (k = 0; k < GW_RUNNING_MAX && gl->running[k]; k++)
		;
	if (ab || k == GW_RUNNING_MAX) {
		job_finish(gl, j, ab ? ab : GW_AB_ROUTE_BUSY, 0);
		return;
	}
	gl->running[k] = j;
	if (!j->hop.via_router) {
		job_sdo(gl, j, false, now_us);
		return;
	}
	ch = sdo_client_lease(gl->node, j->hop.node, 0, 0, job_lease_rx, j, now_us);
	if (ch < 0) {
		job_finish(gl, j, ch == -EALREADY ? GW_AB_ROUTE_BUSY : GW_AB_NO_CLIENT, 0);
		return;
	}
	j->phase = JOB_HOP;
	j->lease_ch = ch;
	j->deadline_us = now_us + (uint64_t)gl->p.sdo_timeout_ms * 2000u;
	gw_netind_encode(d, (gw_netind){ j->net, j->sdo.node });
	sdo_client_lease_send(gl->node, (uint8_t)ch, d);
}

/* The runner is done with a job: hand it back (or answer, if it is ours). */
static void job_finish(struct gw_line *runner, struct gw_job *j, uint32_t abort, uint32_t size)
{
	gw_msg m = { .kind = M_JOB_DONE, .job = j };

	for (unsigned k = 0; k < GW_RUNNING_MAX; k++)
		if (runner->running[k] == j)
			runner->running[k] = NULL;
	j->abort = abort;
	j->size = size;
	j->phase = JOB_SENT;
	if (j->origin == runner->idx) {
		job_respond(runner, j);
		return;
	}
	if (send_to(runner, j->origin, &m))
		COUNT(runner->c.ring_drops); /* the client's own timeout tells it */
}

static void jobs_tick(struct gw_line *gl, uint64_t now_us, uint64_t *next)
{
	for (unsigned k = 0; k < GW_RUNNING_MAX; k++) {
		struct gw_job *j = gl->running[k];
		if (!j || j->phase != JOB_HOP)
			continue;
		if (now_us >= j->deadline_us) {
			sdo_client_lease_end(gl->node, (uint8_t)j->lease_ch, now_us);
			job_finish(gl, j, GW_AB_NO_ANSWER, 0);
		} else if (j->deadline_us < *next) {
			*next = j->deadline_us;
		}
	}
}

static void mbx_gw_sdo(struct gw_line *gl, const mbx_request *req)
{
	mbx_gw_sdo_req r;
	struct gw_job *j = NULL;
	gw_hop hop = { .line = (uint8_t)gl->idx };
	uint32_t ab = 0;
	gw_msg m = { .kind = M_JOB };

	memcpy(&r, req->payload, sizeof r);
	for (unsigned i = 0; i < GW_JOBS && !j; i++)
		if (gl->jobs[i].phase == JOB_FREE)
			j = &gl->jobs[i];
	if (!j) {
		mbx_server_respond(line_mbx(gl->l), &req->reply, MBX_E_BUSY, 0, NULL, 0);
		return;
	}
	if (r.net == gl->p.network_id)
		hop.node = r.sdo.node; /* our own network: a plain transfer here */
	else
		ab = gw_route_resolve(&gl->routes, r.net, r.sdo.node, -1, &hop);
	if (ab) {
		mbx_server_respond(line_mbx(gl->l), &req->reply, MBX_E_ABORT, ab, NULL, 0);
		return;
	}
	memset(&j->hop, 0, sizeof j->hop);
	j->reply = req->reply;
	j->upload = req->code == MBX_CMD_GW_SDO_UPLOAD;
	j->hop = hop;
	j->net = r.net;
	j->sdo = r.sdo;
	/* A single-message request's data lives only during this call. */
	if (req->data_len > j->cap) {
		mbx_server_respond(line_mbx(gl->l), &req->reply, MBX_E_TOO_BIG, 0, NULL, 0);
		return;
	}
	if (req->data_len)
		memcpy(j->buf, req->data, req->data_len);
	j->data = j->buf;
	j->len = (uint32_t)req->data_len;
	j->origin = (uint8_t)gl->idx;
	j->runner = hop.line;
	j->abort = 0;
	j->size = 0;
	j->phase = JOB_SENT;
	if (hop.line == gl->idx) {
		job_run(gl, j, line_loop_now_us(gl->l));
		return;
	}
	m.job = j;
	if (send_to(gl, hop.line, &m)) {
		COUNT(gl->c.ring_drops);
		j->phase = JOB_FREE;
		mbx_server_respond(line_mbx(gl->l), &req->reply, MBX_E_ABORT, GW_AB_ROUTE_BUSY,
				   NULL, 0);
	}
}

/* The routed sessions running on this line, after the routes. */
static size_t list_sessions(struct gw_line *gl, uint8_t *out, uint8_t *count)
{
	uint64_t now_us = line_loop_now_us(gl->l);
	size_t off = 0;

	*count = 0;
	for (uint8_t i = 0; i < gl->n_sess; i++) {
		const struct gw_sess *s = &gl->sess[i];
		mbx_gw_session e = { .channel = i, .target_line = 0xFF };

		if (!gw_sdo_route_busy(&s->r))
			continue;
		if (s->r.opened)
			e.target_line = s->target_line;
		e.router = s->r.hop.via_router ? s->r.hop.node : 0;
		e.node = s->r.target.node;
		e.net = s->net;
		e.age_ms = (uint32_t)((now_us - s->started_us) / 1000u);
		e.frames = (uint32_t)(s->r.frames_to_target + s->r.frames_to_requester);
		snprintf(e.state, sizeof e.state, "%s",
			 gw_sdo_route_state_to_string(gw_sdo_route_state_of(&s->r)));
		memcpy(out + off, &e, sizeof e);
		off += sizeof e;
		(*count)++;
	}
	return off;
}

static void mbx_gw_routes(struct gw_line *gl, const mbx_request *req)
{
	static __thread uint8_t buf[sizeof(mbx_gw_status) + GW_NET_MAX * sizeof(mbx_gw_route) +
				    255 * sizeof(mbx_gw_session)];
	mbx_gw_status st = { .network_id = gl->p.network_id };
	gw_line_counters c;
	size_t off = sizeof st;

	gw_line_counters_get(gl->g, gl->idx, &c);
	st.sessions = c.sessions;
	st.routed = c.routed;
	st.aborted = c.aborted;
	st.timed_out = c.timed_out;
	st.refused = c.refused;
	st.relayed_frames = c.relayed_frames;
	st.pdo_published = c.pdo_published;
	st.pdo_forwarded = c.pdo_forwarded;
	st.pdo_dropped = c.pdo_dropped;
	st.pdo_applied = c.pdo_applied;
	st.pdo_triggered = c.pdo_triggered;
	st.emcy_consumed = c.emcy.consumed;
	st.emcy_forwarded = c.emcy.forwarded;
	st.emcy_unroutable = c.emcy.unroutable;
	st.emcy_dropped = c.emcy.dropped;
	st.emcy_sent = c.emcy.sent;
	st.ring_drops = c.ring_drops;
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		st.leases += gl->relay[i].used;
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++) {
		const gw_route *r = &gl->routes.r[n];
		mbx_gw_route e = { .net = (uint8_t)n,
				   .kind = r->kind,
				   .line = r->line,
				   .router = r->router,
				   .raw = r->raw,
				   .routed = r->count[GW_OUT_ROUTED],
				   .aborted = r->count[GW_OUT_ABORTED],
				   .timed_out = r->count[GW_OUT_TIMED_OUT],
				   .refused = r->count[GW_OUT_REFUSED] };
		if (r->kind == GW_ROUTE_NONE && !e.routed && !e.aborted && !e.timed_out &&
		    !e.refused)
			continue;
		memcpy(buf + off, &e, sizeof e);
		off += sizeof e;
		st.routes++;
	}
	off += list_sessions(gl, buf + off, &st.active);
	memcpy(buf, &st, sizeof st);
	mbx_server_respond(line_mbx(gl->l), &req->reply, 0, 0, buf, off);
}

static void ext_command(void *ctx, line *l, const mbx_request *req)
{
	struct gw_line *gl = ctx;

	(void)l;
	switch (req->code) {
	case MBX_CMD_GW_ROUTES:
		mbx_gw_routes(gl, req);
		break;
	case MBX_CMD_GW_SDO_UPLOAD:
	case MBX_CMD_GW_SDO_DOWNLOAD:
		mbx_gw_sdo(gl, req);
		break;
	default:
		mbx_server_respond(line_mbx(gl->l), &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
		break;
	}
}

/* ---- 1F2Ch ------------------------------------------------------------------------------ */

static uint32_t routes_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct gw_line *gl = ctx;

	(void)e;
	return gw_route_write_check(a, (uint8_t)gl->g->n);
}

static void routes_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct gw_line *gl = ctx;

	(void)e;
	(void)a;
	gw_route_table_compile_od(&gl->routes, co_node_od(gl->node));
}

static const co_od_hooks routes_hooks = {
	.check_write = routes_check,
	.after_write = routes_written,
};

/* ---- the extension ops --------------------------------------------------------------------- */

static int ext_attach(void *ctx, line *l)
{
	struct gw_line *gl = ctx;
	co_od *od;
	int rc;

	gl->l = l;
	gl->node = line_node(l);
	gl->carried = true; /* no lease to end before the first look */
	od = co_node_od(gl->node);
	gw_route_table_init(&gl->routes, (uint8_t)gl->idx, (uint8_t)gl->g->n);
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++)
		co_od_set_hooks(od, GW_OBJ_ROUTES, (uint8_t)n, &routes_hooks, gl);
	gw_route_table_compile_od(&gl->routes, od);
	for (size_t i = 0; i < gw_image_count(gl->g->img); i++) {
		const gw_image_slot *is = gw_image_slot_at(gl->g->img, (int)i);
		co_od_set_hooks(od, is->index, is->sub, &image_hooks, gl);
	}
	if ((rc = gw_fwd_list_init(&gl->fwd, gl->g->img)))
		return rc;
	if ((rc = gw_pdo_sync_init(&gl->lost, gw_image_count(gl->g->img))))
		return rc;
	gw_fwd_list_rebuild(&gl->fwd, gl->g->img, od);
	gl->n_sess = sdo_server_channel_count(gl->node);
	gl->sess = calloc(gl->n_sess ? gl->n_sess : 1, sizeof(*gl->sess));
	if (!gl->sess)
		return -ENOMEM;
	for (uint8_t i = 0; i < gl->n_sess; i++) {
		gl->sess[i].gl = gl;
		gl->sess[i].ch = i;
		gw_sdo_route_init(&gl->sess[i].r, &sess_ops, &gl->sess[i]);
	}
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		gl->relay[i].gl = gl;
	for (unsigned i = 0; i < GW_JOBS; i++) {
		gl->jobs[i].cap = gl->g->max_transfer;
		gl->jobs[i].buf = malloc(gl->g->max_transfer);
		if (!gl->jobs[i].buf)
			return -ENOMEM;
	}
	return sdo_server_route_attach(gl->node, &server_hook, gl);
}

/* Remove the hooks this line's gateway set on index:sub (and no other). */
static void unhook(co_od *od, uint16_t index, uint8_t sub, const struct gw_line *gl)
{
	co_od_entry *e = co_od_find(od, index, sub);

	if (e && e->hook_ctx == gl)
		co_od_entry_set_hooks(e, NULL, NULL);
}

static void ext_detach(void *ctx, line *l)
{
	struct gw_line *gl = ctx;
	co_od *od = co_node_od(line_node(l));

	sdo_server_route_attach(line_node(l), NULL, NULL);
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++)
		unhook(od, GW_OBJ_ROUTES, (uint8_t)n, gl);
	for (size_t i = 0; i < gw_image_count(gl->g->img); i++) {
		const gw_image_slot *is = gw_image_slot_at(gl->g->img, (int)i);
		unhook(od, is->index, is->sub, gl);
	}
	free(gl->sess);
	gl->sess = NULL;
	gl->n_sess = 0;
	for (unsigned i = 0; i < GW_JOBS; i++) {
		free(gl->jobs[i].buf);
		gl->jobs[i].buf = NULL;
	}
	gw_fwd_list_fini(&gl->fwd);
	gw_pdo_sync_fini(&gl->lost);
}

static void ext_event(void *ctx, line *l, const co_event *ev)
{
	struct gw_line *gl = ctx;

	(void)l;
	switch (ev->kind) {
	case CO_EV_EMCY_RX:
		emcy_consumed(gl, &ev->u.emcy);
		break;
	case CO_EV_OD_WRITTEN:
		if (ev->u.od.index >= CO_PDO_TPDO_COMM && ev->u.od.index < 0x1C00)
			gl->fwd_dirty = true;
		break;
	case CO_EV_NMT_STATE:
	case CO_EV_RESTORE:
		/* a reset brought 1F2Ch back to its defaults without hooks */
		gw_route_table_compile_od(&gl->routes, co_node_od(gl->node));
		gl->fwd_dirty = true;
		break;
	default:
		break;
	}
}

static void handle(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	struct gw_sess *s;
	struct gw_relay *r;

	switch (m->kind) {
	case M_FWD:
		/* The value this update carried, in the order the source wrote
		 * them: each gets its own TPDO when the TPDO's timing allows
		 * one (an inhibit time sends the latest at its end). */
		pdo_fwd_received(gl, m, now_us);
		break;
	case M_EMCY:
		emcy_send(gl, m);
		break;
	case M_OPEN:
		relay_open(gl, m, now_us);
		break;
	case M_TO_TARGET:
		if ((r = relay_by_sid(gl, m->from, m->sid))) {
			if (!r->engaged)
				memcpy(r->mux, &m->d[1], sizeof r->mux);
			r->engaged = true;
			r->last_us = now_us;
			COUNT(gl->c.relayed_frames);
			sdo_client_lease_send(gl->node, (uint8_t)r->cli_ch, m->d);
		}
		break;
	case M_CLOSE:
		if ((r = relay_by_sid(gl, m->from, m->sid)))
			relay_free(r, now_us);
		break;
	case M_OPENED:
		if ((s = sess_by_sid(gl, m->sid)))
			gw_sdo_route_opened(&s->r, m->abort, now_us);
		else if (!m->abort) {
			/* the session is gone: give the lease straight back */
			gw_msg c = { .kind = M_CLOSE, .sid = m->sid };
			if (send_to(gl, m->from, &c))
				COUNT(gl->c.ring_drops);
		}
		break;
	case M_TO_REQ:
		if ((s = sess_by_sid(gl, m->sid)))
			gw_sdo_route_target_frame(&s->r, m->d, now_us);
		break;
	case M_LOST:
		if ((s = sess_by_sid(gl, m->sid)))
			gw_sdo_route_lost(&s->r, m->abort, now_us);
		break;
	case M_JOB:
		job_run(gl, m->job, now_us);
		break;
	case M_JOB_DONE:
		job_respond(gl, m->job);
		break;
	default:
		break;
	}
}

static void ext_wake(void *ctx, line *l)
{
	struct gw_line *gl = ctx;
	uint64_t now_us = line_loop_now_us(l);
	gw_msg m;

	for (unsigned from = 0; from < gl->g->n; from++) {
		xring *r = xring_mesh_get(gl->g->mesh, from, gl->idx);
		if (!r)
			continue;
		while (xring_pop(r, &m, sizeof(m)) > 0)
			handle(gl, &m, now_us);
	}
	/* After the rings: a resync bit is set only on a full ring, whose
	 * messages have woken us, so it is seen here at the latest. */
	gw_pdo_sync_take(&gl->lost, gl->g->img, pdo_resync_apply, gl);
}

static uint64_t ext_poll(void *ctx, line *l, uint64_t now_us)
{
	struct gw_line *gl = ctx;
	uint64_t next = now_us + GW_REBUILD_US;
	uint64_t idle = (uint64_t)gl->p.sdo_timeout_ms * 1000u * GW_RELAY_IDLE_FACTOR;

	(void)l;
	for (uint8_t i = 0; i < gl->n_sess; i++) {
		gw_sdo_route_tick(&gl->sess[i].r, now_us);
		if (gw_sdo_route_deadline(&gl->sess[i].r) < next)
			next = gw_sdo_route_deadline(&gl->sess[i].r);
	}
	bool held = false;

	for (unsigned i = 0; i < GW_RELAYS_MAX; i++) {
		struct gw_relay *r = &gl->relay[i];
		if (!r->used)
			continue;
		if (now_us - r->last_us >= idle) {
			relay_free(r, now_us);
			continue;
		}
		held = true;
		if (r->last_us + idle < next)
			next = r->last_us + idle;
	}
	if (held)
		relays_check_link(gl, now_us, &next);
	jobs_tick(gl, now_us, &next);
	/* Mailbox writes to the mapping leave no event: look once a second. */
	if (gl->fwd_dirty || now_us >= gl->next_rebuild_us) {
		gw_fwd_list_rebuild(&gl->fwd, gl->g->img, co_node_od(gl->node));
		gl->fwd_dirty = false;
		gl->next_rebuild_us = now_us + GW_REBUILD_US;
	}
	if (gl->next_rebuild_us < next)
		next = gl->next_rebuild_us;
	return next;
}

static const line_ext_ops gw_ext_ops = {
	.name = "gateway",
	.attach = ext_attach,
	.detach = ext_detach,
	.on_core_event = ext_event,
	.cmd_first = MBX_CMD_GW_ROUTES,
	.cmd_last = MBX_CMD_GW_SDO_DOWNLOAD,
	.on_command = ext_command,
	.on_wake = ext_wake,
	.poll = ext_poll,
};

/* ---- life cycle ------------------------------------------------------------------------------- */

static int image_from_od(gw_image *img, const co_od *od)
{
	for (size_t i = 0; od && i < co_od_count(od); i++) {
		const co_od_entry *e = co_od_at(od, i);
		int rc;

		if (!gw_image_in_range(e->index) || co_type_is_variable((co_type)e->type) ||
		    e->size < 1 || e->size > 8 || (e->obj_code != CO_OBJ_VAR && e->sub == 0))
			continue;
		rc = gw_image_add(img, e->index, e->sub, (uint8_t)e->size,
				  gw_image_bits_from(e->data, (uint8_t)e->size));
		if (rc)
			return rc;
	}
	gw_image_seal(img);
	return 0;
}

int gw_create(gw **out, const gw_params *p)
{
	gw *g;
	int rc;

	if (!p || p->n_lines < 1 || p->n_lines > GW_LINES_MAX)
		return -EINVAL;
	g = calloc(1, sizeof(*g));
	if (!g)
		return -ENOMEM;
	g->n = p->n_lines;
	g->max_transfer = p->max_transfer ? p->max_transfer : 1024u * 1024u;
	rc = gw_image_create(&g->img, GW_IMAGE_MAX_SLOTS);
	if (!rc)
		rc = image_from_od(g->img, p->image_od);
	/* The mesh wants at least two lines; one line routes nothing. */
	if (!rc && g->n >= 2)
		rc = xring_mesh_create(&g->mesh, g->n, NULL,
				       p->ring_slots ? p->ring_slots : GW_RING_SLOTS,
				       sizeof(gw_msg));
	for (unsigned i = 0; !rc && i < g->n; i++) {
		g->line[i].g = g;
		g->line[i].idx = i;
		g->line[i].p = p->line[i];
		if (!g->line[i].p.sdo_timeout_ms)
			g->line[i].p.sdo_timeout_ms = 1000;
	}
	if (rc) {
		gw_destroy(g);
		return rc;
	}
	*out = g;
	return 0;
}

void gw_destroy(gw *g)
{
	if (!g)
		return;
	xring_mesh_destroy(g->mesh);
	gw_image_destroy(g->img);
	free(g);
}

void gw_line_ext(gw *g, unsigned line_no, line_ext *out)
{
	out->ops = NULL;
	out->ctx = NULL;
	out->wake_fd = -1;
	if (!g || line_no >= g->n)
		return;
	out->ops = &gw_ext_ops;
	out->ctx = &g->line[line_no];
	out->wake_fd = g->mesh ? xring_mesh_wake_fd(g->mesh, line_no) : -1;
}

void gw_line_counters_get(gw *g, unsigned line_no, gw_line_counters *out)
{
	const uint64_t *src;
	uint64_t *dst = (uint64_t *)out;

	memset(out, 0, sizeof(*out));
	if (!g || line_no >= g->n)
		return;
	src = (const uint64_t *)&g->line[line_no].c;
	for (size_t i = 0; i < sizeof(*out) / sizeof(uint64_t); i++)
		dst[i] = __atomic_load_n(&src[i], __ATOMIC_RELAXED);
}
