/* SPDX-License-Identifier: MIT */
/*
 * gateway/gateway.c - the gateway as a line extension (gateway.h): the
 * ops every line runs, where each message and tick goes (gw_line.h names
 * the file for each), the 1F2Ch hooks and the life cycle.
 *
 * A routed SDO transfer touches two lines: the entry line owns the
 * transfer (a routed session of its SDO server, gw_session.c, or a mailbox
 * transfer of lines/line_sdo.c with its hop, gw_mbx_hop.c) and the target
 * line owns a relay lease (one SDO client channel of its pool, toward the
 * target node or the next router, gw_relay.c). They exchange fixed-size
 * messages over the rings: OPEN (the lease the entry line reserved on the
 * target's lending board, gateway/lend.h), frames both ways, CLOSE, LOST.
 * A frame usually goes on the other line's bus from the thread that has
 * it, its message only telling the owner (gw_send_across).
 */
#include "gateway/gateway.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/pdo.h"
#include "core/sdo_server.h"
#include "gateway/convention.h"
#include "gateway/gw_line.h"
#include "lines/socketcan.h"
#include "mailbox/proto.h"
#include "mailbox/server.h"

static void ext_command(void *ctx, line *l, const mbx_request *req)
{
	struct gw_line *gl = ctx;

	(void)l;
	if (req->code == MBX_CMD_GW_ROUTES)
		gw_mbx_routes(gl, req);
	else
		mbx_server_respond(line_mbx(gl->l), &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
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
		co_od_set_hooks(od, is->index, is->sub, &gw_image_hooks, gl);
	}
	if ((rc = gw_fwd_list_init(&gl->fwd, gl->g->img)))
		return rc;
	for (unsigned i = 0; i < gl->p.n_pinned; i++)
		gw_fwd_list_pin(&gl->fwd, gw_image_find(gl->g->img, gl->p.pinned[i], 0));
	if ((rc = gw_pdo_sync_init(&gl->lost, gw_image_count(gl->g->img))))
		return rc;
	gw_fwd_list_rebuild(&gl->fwd, gl->g->img, od);
	/* All lines are created (attached) before any starts: the other
	 * lines' threads read these only once they run. A socket that cannot
	 * be opened leaves that pair on the hand-off. */
	for (unsigned i = 0; i < GW_LINES_MAX; i++)
		gl->peer_fd[i] = -1;
	for (unsigned i = 0; i < gl->g->n; i++)
		if (i != gl->idx)
			gl->peer_fd[i] = can_tx_socket_open(line_ifname(gl->l));
	if ((rc = gw_fast_attach(gl)))
		return rc;
	gl->n_sess = sdo_server_channel_count(gl->node);
	gl->sess = calloc(gl->n_sess ? gl->n_sess : 1, sizeof(*gl->sess));
	if (!gl->sess)
		return -ENOMEM;
	gw_sessions_init(gl);
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		gl->relay[i].gl = gl;
	gw_lend_attach(gl);
	return sdo_server_route_attach(gl->node, &gw_session_server_hook, gl);
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
	gw_lend_detach(gl);
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++)
		unhook(od, GW_OBJ_ROUTES, (uint8_t)n, gl);
	for (size_t i = 0; i < gw_image_count(gl->g->img); i++) {
		const gw_image_slot *is = gw_image_slot_at(gl->g->img, (int)i);
		unhook(od, is->index, is->sub, gl);
	}
	free(gl->sess);
	gl->sess = NULL;
	gl->n_sess = 0;
	gw_fast_detach(gl);
	for (unsigned i = 0; i < GW_LINES_MAX; i++) {
		if (gl->peer_fd[i] >= 0)
			close(gl->peer_fd[i]);
		gl->peer_fd[i] = -1;
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
		gw_emcy_consumed(gl, &ev->u.emcy);
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

/* The entry line's side of a lease: a session's or a mailbox hop's. */
static void handle_answer(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	bool hop = m->sid & GW_SID_HOP;

	switch (m->kind) {
	case M_TO_REQ:
		hop ? gw_hop_target_frame(gl, m, now_us) : gw_session_target_frame(gl, m, now_us);
		break;
	case M_LOST:
		hop ? gw_hop_lost(gl, m, now_us) : gw_session_lost(gl, m, now_us);
		break;
	default:
		break;
	}
}

static void handle(struct gw_line *gl, const gw_msg *m, uint64_t now_us)
{
	switch (m->kind) {
	case M_FWD:
		/* The value this update carried, in the order the source wrote
		 * them: each gets its own TPDO when the TPDO's timing allows
		 * one (an inhibit time sends the latest at its end). */
		gw_pdo_received(gl, m, now_us);
		break;
	case M_EMCY:
		gw_emcy_send(gl, m);
		break;
	case M_OPEN:
		gw_relay_open(gl, m, now_us);
		break;
	case M_TO_TARGET:
		gw_relay_to_target(gl, m, now_us);
		break;
	case M_CLOSE:
		gw_relay_close(gl, m, now_us);
		break;
	default:
		handle_answer(gl, m, now_us);
		break;
	}
}

/* What this line handed itself (a hop through a router on its own bus). */
static void take_own(struct gw_line *gl, uint64_t now_us)
{
	gw_msg m;

	while (gw_self_take(gl, &m))
		handle(gl, &m, now_us);
}

/* Everything the other lines pushed; true if anything came. */
static bool take_rings(struct gw_line *gl, uint64_t now_us)
{
	bool any = false;
	gw_msg m;

	for (unsigned from = 0; from < gl->g->n; from++) {
		xring *r = xring_mesh_get(gl->g->mesh, from, gl->idx);
		if (!r)
			continue;
		while (xring_pop(r, &m, sizeof(m)) > 0) {
			handle(gl, &m, now_us);
			gl->handled_from[from]++;
			any = true;
		}
	}
	return any;
}

/* Updates pushed without waking us (gw_send_quiet_to) are applied before
 * whatever woke us now is handled. */
static void ext_before_events(void *ctx, line *l)
{
	struct gw_line *gl = ctx;

	if (take_rings(gl, line_loop_now_us(l)))
		gw_publish_done(gl);
}

static void ext_wake(void *ctx, line *l)
{
	struct gw_line *gl = ctx;
	uint64_t now_us = line_loop_now_us(l);

	take_rings(gl, now_us);
	gw_publish_done(gl);
	take_own(gl, now_us);
	/* After the rings: a resync bit is set only on a full ring, whose
	 * messages have woken us, so it is seen here at the latest. */
	gw_pdo_sync_take(&gl->lost, gl->g->img, gw_pdo_resync_apply, gl);
}

static uint64_t ext_poll(void *ctx, line *l, uint64_t now_us)
{
	struct gw_line *gl = ctx;
	uint64_t next = now_us + GW_REBUILD_US;

	(void)l;
	take_own(gl, now_us);
	next = gw_sessions_tick(gl, now_us, next);
	next = gw_relays_tick(gl, now_us, next);
	/* Mailbox writes to the mapping leave no event, but the core resets
	 * the TPDO they change (the fast TPDOs' gate hears it: stale); other
	 * changes are looked for once a second. */
	if (gl->fwd_dirty || gl->fast.stale || now_us >= gl->next_rebuild_us) {
		gw_fwd_list_rebuild(&gl->fwd, gl->g->img, co_node_od(gl->node));
		gw_fast_refresh(gl);
		gl->fwd_dirty = false;
		gl->next_rebuild_us = now_us + GW_REBUILD_US;
	}
	if (gl->next_rebuild_us < next)
		next = gl->next_rebuild_us;
	gw_fast_poll(gl);
	gw_wake_owed(gl);
	/* sent to itself during this look: the line looks again at once */
	return gl->self_len ? now_us : next;
}

static const line_ext_ops gw_ext_ops = {
	.name = "gateway",
	.attach = ext_attach,
	.detach = ext_detach,
	.on_core_event = ext_event,
	.cmd_first = MBX_CMD_GW_ROUTES,
	.cmd_last = MBX_CMD_GW_ROUTES,
	.on_command = ext_command,
	.on_wake = ext_wake,
	.before_events = ext_before_events,
	.poll = ext_poll,
	.sdo_route = gw_hop_route,
	.sdo_route_end = gw_hop_end,
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
