/* SPDX-License-Identifier: MIT */
/*
 * lines/line_sdo.c - mailbox SDO_UPLOAD / SDO_DOWNLOAD: a client of the
 * mailbox reads or writes an object of a remote node through the line's
 * SDO client (core/sdo_client.c). The whole transaction is here:
 *
 *   1. sdo_transfer()     the command arrives (already validated by the
 *                         mailbox); a pending slot keeps the reply address
 *                         and the buffer; for a node of a network
 *                         (MBX_CMD_GW_SDO_*) the routing step asks the
 *                         extension that routes (the gateway, line_ext.h
 *                         sdo_route) how the frames reach it: this line's
 *                         bus, or a relay to another line; the request
 *                         goes to the SDO client pool with sdo_done() as
 *                         its confirmation.
 *   2. core/sdo_client.c  borrows a free channel (or queues the request),
 *                         runs the CiA 301 protocol, ends the transfer.
 *   3. sdo_done()         the confirmation: give the route back, answer
 *                         the requester (data or abort code), tell SDO
 *                         observers (MBX_EV_SDO_DONE), release the slot.
 *
 * A client that goes away has its transfers cancelled where they are
 * (line_sdo_client_gone): the answer could not be delivered, and the
 * channel would stay busy for nothing.
 *
 * So local and routed requests share the budget, the chunking, the
 * cancel, the "busy" answer of a full pool and the slot's lifetime; a
 * routed transfer differs only in where its frames go.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/sdo_client.h"

/* A routed transfer ended: its route is given back. Whether it was one. */
static bool route_end(line *l, line_pending *pp)
{
	if (pp->route_ext == LINE_NO_ROUTE)
		return false;
	const line_ext *x = &l->p.ext[pp->route_ext];
	x->ops->sdo_route_end(x->ctx, l, pp->tag);
	pp->route_ext = LINE_NO_ROUTE;
	return true;
}

/* Step 3: the SDO client confirms the transfer (exactly once, on the line
 * thread, never inside sdo_client_pool_submit). */
static void sdo_done(void *arg, const co_ev_sdo_cli *c)
{
	line *l = arg;
	line_pending *pp = line_pending_find(&l->pending, c->tag);
	if (!pp)
		return; /* its client went away and the slot was released */
	uint32_t abort = c->abort;
	/* CiA 302-7: a node that never answered is "unknown" to a request
	 * addressed by network, whichever way it went */
	if (route_end(l, pp) && abort == SDO_AB_TIMEOUT && !c->answered)
		abort = SDO_AB_NODE_UNKNOWN;
	/* the answer pays its own copy of the data from the budget */
	line_pending_pay_back(pp);
	if (pp->answer && !pp->over_budget)
		pp->answer(pp->answer_ctx, l, &pp->reply, abort, c->upload ? pp->buf : NULL,
			   c->upload ? c->size : 0);
	else if (pp->over_budget)
		line_answer(l, &pp->reply, MBX_E_NO_MEMORY, 0, NULL, 0);
	else if (abort)
		line_answer(l, &pp->reply, MBX_E_ABORT, abort, NULL, 0);
	else if (c->upload)
		line_answer(l, &pp->reply, 0, 0, pp->buf, c->size);
	else
		line_answer(l, &pp->reply, 0, 0, NULL, 0);
	/* SDO-class subscribers (a logger, say) see every transfer end */
	mbx_ev_sdo_done done = {
		.abort = abort,
		.size = c->size,
		.index = c->index,
		.sub = c->sub,
		.node = c->node_id,
		.upload = c->upload,
		.mode = c->mode,
		.client = pp->reply.client,
	};
	mbx_server_publish(l->mbx, MBX_EV_SDO_DONE, pp->reply.corr, &done, sizeof done);
	line_pending_release(&l->pending, pp);
}

/* A big upload's data: into the slot's buffer, paid from the daemon's
 * transfer memory budget as it arrives (-ENOMEM aborts the transfer with
 * 05040005 and the requester gets MBX_E_NO_MEMORY). */
static int upload_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
		       uint32_t total)
{
	line_pending *pp = ctx;
	int rc = line_pending_grow(pp, offset + len, total);
	if (rc < 0)
		return rc;
	memcpy(pp->buf + offset, data, len);
	return 0;
}

/* The extension that routes SDO requests addressed by network, or -1. */
static int route_ext(const line *l)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->sdo_route && x->ops->sdo_route_end)
			return (int)i;
	}
	return -1;
}

/* Step 1, the routing step: how the frames of pp's transfer reach node
 * `r->node_id` of network `net` (r filled in), or the abort refusing it. */
static uint32_t route(line *l, line_pending *pp, uint16_t net, sdo_client_req *r)
{
	int xi = route_ext(l);
	line_sdo_route rt = { 0 };
	const line_ext *x = &l->p.ext[xi];
	uint32_t abort = x->ops->sdo_route(x->ctx, l, pp->tag, net, r->node_id, &rt);

	if (abort)
		return abort;
	pp->route_ext = (uint8_t)xi;
	r->node_id = rt.node;
	r->relay = rt.relay;
	r->relay_ctx = rt.relay_ctx;
	r->relay_target = rt.relay_target;
	return 0;
}

/* A slot for the request. Big transfers need one with a max_transfer
 * buffer (uploads) or keep the chunked command's data (downloads); a small
 * upload also fits a small slot's inline buffer. */
static line_pending *take_slot(line *l, const mbx_request *req, const mbx_sdo_req *s, bool upload)
{
	bool big = upload ? (s->size == 0 || s->size > LINE_INLINE_MAX)
			  : req->data_len > LINE_INLINE_MAX;
	line_pending *pp = line_pending_take(&l->pending, req, LINE_PENDING_SDO, big);
	if (!pp && big && upload)
		pp = line_pending_take(&l->pending, req, LINE_PENDING_SDO, false);
	return pp;
}

/* Where the transfer's data comes from or goes to. */
static void set_data(sdo_client_req *r, line_pending *pp, const mbx_request *req,
		     const mbx_sdo_req *s)
{
	if (r->upload && pp->budget) {
		r->size = s->size;
		r->sink = upload_sink;
		r->ctx = pp;
	} else if (r->upload) {
		r->size = s->size;
		r->buf = pp->buf;
		r->cap = pp->cap;
	} else if (req->data_len <= LINE_INLINE_MAX) {
		/* a single-message command's data lives only during dispatch */
		r->size = (uint32_t)req->data_len;
		memcpy(pp->inline_data, req->data, req->data_len);
		r->data = pp->inline_data;
	} else {
		r->size = (uint32_t)req->data_len;
		r->data = req->data; /* chunked: valid until answered */
	}
}

/* Step 1: park the request, route it (net: a network, 0 = this line's
 * bus), hand it to the SDO client pool. An extension's request (answer
 * set) gets its answer shaped by `answer` at the confirmation. */
static bool sdo_transfer(line *l, const mbx_request *req, const mbx_sdo_req *s, uint16_t net,
			 bool upload, line_sdo_answer_fn answer, void *answer_ctx)
{
	if (!sdo_client_channel_count(l->node) || (net && route_ext(l) < 0)) {
		line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
		return false;
	}
	line_pending *pp = take_slot(l, req, s, upload);
	if (!pp) {
		line_answer(l, &req->reply, MBX_E_BUSY, 0, NULL, 0);
		return false;
	}
	pp->answer = answer;
	pp->answer_ctx = answer_ctx;

	/* timeout_ms 0 means "the line's default" (docs/mailbox.md): the SDO
	 * client's own per-frame timeout (cfg.sdo_client_timeout_ms, which
	 * cogwd sets from lines[].sdo_timeout_ms), not the SDO server's. */
	sdo_client_req r = {
		.upload = upload,
		.node_id = s->node,
		.index = s->index,
		.sub = s->sub,
		.mode = s->mode,
		.timeout_ms = s->timeout_ms,
		.tag = pp->tag,
		.con = sdo_done,
		.con_arg = l,
	};
	set_data(&r, pp, req, s);
	uint32_t abort = net ? route(l, pp, net, &r) : 0;
	if (abort) {
		line_pending_release(&l->pending, pp);
		line_answer(l, &req->reply, MBX_E_ABORT, abort, NULL, 0);
		return false;
	}
	if (!r.relay && r.node_id == co_node_id(l->node) && !answer) {
		/* with ourselves: our own dictionary answers (line_od.c) */
		route_end(l, pp);
		line_pending_release(&l->pending, pp);
		line_od_sdo_own(l, req, s->index, s->sub, upload);
		return true;
	}
	int rc = -EINVAL; /* an extension's transfer with ourselves */
	if (r.relay || r.node_id != co_node_id(l->node))
		rc = sdo_client_pool_submit(l->node, &r, l->now_us);
	if (rc < 0) {
		route_end(l, pp);
		line_pending_release(&l->pending, pp);
		line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
		return false;
	}
	return true;
}

static void sdo_transfer_local(line *l, const mbx_request *req, bool upload)
{
	mbx_sdo_req s;
	memcpy(&s, req->payload, sizeof s);
	sdo_transfer(l, req, &s, 0, upload, NULL, NULL);
}

void line_sdo_upload(line *l, const mbx_request *req)
{
	sdo_transfer_local(l, req, true);
}

void line_sdo_download(line *l, const mbx_request *req)
{
	sdo_transfer_local(l, req, false);
}

/* MBX_CMD_GW_SDO_*: the same transfer with a node of network `net`. */
static void sdo_transfer_net(line *l, const mbx_request *req, bool upload)
{
	mbx_gw_sdo_req g;
	memcpy(&g, req->payload, sizeof g);
	sdo_transfer(l, req, &g.sdo, g.net, upload, NULL, NULL);
}

void line_sdo_upload_net(line *l, const mbx_request *req)
{
	sdo_transfer_net(l, req, true);
}

void line_sdo_download_net(line *l, const mbx_request *req)
{
	sdo_transfer_net(l, req, false);
}

bool line_sdo_submit(line *l, const mbx_request *req, const line_sdo_xfer *x)
{
	mbx_sdo_req s = { .node = x->node, .index = x->index, .sub = x->sub, .size = x->size_hint };
	return sdo_transfer(l, req, &s, 0, x->upload, x->answer, x->ctx);
}

void line_sdo_client_gone(line *l, uint32_t client)
{
	for (unsigned i = 0; i < LINE_PENDING_MAX; i++) {
		line_pending *pp = line_pending_at(&l->pending, i);
		if (!pp->used || pp->kind != LINE_PENDING_SDO || pp->reply.client != client)
			continue;
		/* Exactly this request, wherever it is: running (an abort
		 * frame goes out) or still waiting for a channel. Its
		 * confirmation (sdo_done) comes at once and releases the slot;
		 * observers still see the transfer end. */
		if (sdo_client_cancel_tag(l->node, pp->tag, SDO_AB_GENERAL, l->now_us) < 0) {
			route_end(l, pp);
			line_pending_release(&l->pending, pp);
		}
	}
}
