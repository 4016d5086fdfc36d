/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_dispatch.c - the way in: one received message through
 * the header checks, its sender's token, validation, access and the
 * request's own limits, to where it is handled: REGISTER, a protocol
 * command, a chunk of a transfer, or the line's dispatcher (cfg.dispatch),
 * with the per-client and per-line limits of requests in flight.
 */
#include "mailbox/server_int.h"

#include <stddef.h>
#include <string.h>

static unsigned read_outstanding(const mbx_server *srv)
{
	unsigned n = 0;

	for (unsigned i = 0; i < srv->cfg.max_clients; i++)
		if (srv->clients[i].id && srv->clients[i].access < MBX_ACCESS_WRITE)
			n += srv->clients[i].outstanding;
	return n;
}

/* The request's own timeout (SDO per frame, LSS per answer) within the
 * ceiling: 0xFFFFFFFF would hold an SDO channel for ever. */
static bool timeout_too_long(const mbx_server *srv, const mbx_hdr *h, const uint8_t *p)
{
	uint32_t t;

	switch (h->code) {
	case MBX_CMD_SDO_UPLOAD:
	case MBX_CMD_SDO_DOWNLOAD:
		memcpy(&t, p + offsetof(mbx_sdo_req, timeout_ms), sizeof t);
		break;
	case MBX_CMD_LSS_SWITCH_GLOBAL ... MBX_CMD_LSS_FASTSCAN:
		memcpy(&t, p + offsetof(mbx_lss_req, timeout_ms), sizeof t);
		break;
	default:
		return false;
	}
	return t > srv->cfg.max_request_timeout_ms;
}

static void dispatch(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *fixed,
		     size_t fixed_len, const uint8_t *data, size_t data_len, mbx_xfer *held)
{
	mbx_request req = {
		.reply = { .client = c->id,
			   .code = h->code,
			   .flags = h->flags & MBX_F_NO_REPLY,
			   .corr = h->corr },
		.code = h->code,
		.line = srv->cfg.line,
		.access = c->access,
		.uid = c->uid,
		.pid = c->pid,
		.payload = fixed,
		.fixed_len = fixed_len,
		.data = data,
		.data_len = data_len,
	};

	if (held)
		req.reply.slot = (uint8_t)(held - srv->xfers + 1);
	srv->stats.commands_ok++;
	/* Counted until mbx_server_respond(); over a limit the request is
	 * answered BUSY at once (which uncounts it again). */
	c->outstanding++;
	if (c->outstanding > srv->cfg.max_outstanding ||
	    (c->access < MBX_ACCESS_WRITE && read_outstanding(srv) > srv->cfg.read_outstanding)) {
		srv->stats.limited++;
		mbx_server_respond(srv, &req.reply, MBX_E_BUSY, 0, NULL, 0);
		return;
	}
	if (!srv->cfg.dispatch.dispatch) {
		mbx_server_respond(srv, &req.reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
		return;
	}
	srv->cfg.dispatch.dispatch(srv->cfg.dispatch_ctx, srv, &req);
}

/* The header checks every command passes first: 0 or a status, *bad the
 * reason. */
static int check_header(const mbx_server *srv, const uint8_t *buf, size_t n, mbx_hdr *h,
			mbx_bad *bad)
{
	int rc = mbx_hdr_decode(buf, n, h, bad);

	if (rc == 0 && h->kind != MBX_KIND_COMMAND) {
		*bad = MBX_BAD_KIND;
		return MBX_E_MALFORMED;
	}
	if (rc == 0 && h->line != srv->cfg.line) {
		*bad = MBX_BAD_LINE;
		return MBX_E_BAD_LINE;
	}
	return rc;
}

/* The sender, authenticated by its token; NULL when unknown, or when the
 * header is too broken to name one. Only an authenticated sender gets an
 * answer, even an error answer: a forged client id must not make us write
 * to somebody else's queue. */
static mbx_client *sender_of(const mbx_server *srv, const mbx_hdr *h, mbx_bad bad)
{
	mbx_client *c;

	if (bad == MBX_BAD_SHORT || bad == MBX_BAD_MAGIC)
		return NULL;
	c = srv_client_find(srv, h->client);
	return c && c->token == h->token ? c : NULL;
}

/* A chunk of a transfer already refused: ignored (the last one ends it). */
static bool discarded(mbx_client *c, const mbx_hdr *h)
{
	if (!c->discarding || c->discard_corr != h->corr || !(h->flags & MBX_F_CHUNKED) ||
	    h->chunk == 0)
		return false;
	if (!(h->flags & MBX_F_MORE))
		c->discarding = false;
	return true;
}

/* A command of c refused with status: the rest of its transfer (when this
 * is the first of several chunks) is ignored, and the client is told when
 * tell and it did not ask for no reply. */
static void refuse_command(mbx_server *srv, mbx_client *c, const mbx_hdr *h, int status, bool tell)
{
	if ((h->flags & MBX_F_MORE) && h->chunk == 0) {
		c->discarding = true;
		c->discard_corr = h->corr;
	}
	if (tell && !(h->flags & MBX_F_NO_REPLY))
		srv_send_status(srv, c, h->code, h->corr, status, 0, NULL, 0);
}

/* Validation, access and the request's own timeout: 0 when c may run the
 * command, else a status (refused and counted here). */
static int admit(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_bad bad = MBX_BAD_NONE;
	int rc = mbx_cmd_validate(h, p, &bad);

	if (rc) {
		srv_count_bad(srv, bad);
		refuse_command(srv, c, h, rc, true);
		return rc;
	}
	if ((mbx_cmd_lookup(h->code)->flags & MBX_CI_WRITE) && c->access < MBX_ACCESS_WRITE) {
		srv->stats.access_denied++;
		refuse_command(srv, c, h, MBX_E_ACCESS, h->chunk == 0);
		return MBX_E_ACCESS;
	}
	if ((!(h->flags & MBX_F_CHUNKED) || h->chunk == 0) && timeout_too_long(srv, h, p)) {
		srv_count_bad(srv, MBX_BAD_PARAM);
		refuse_command(srv, c, h, MBX_E_PARAM, true);
		return MBX_E_PARAM;
	}
	return 0;
}

/* A chunk to its transfer; the command goes to the line once complete,
 * with the flags of its first chunk. */
static void run_chunk(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_xfer *x = srv_chunk_in(srv, c, h, p);
	mbx_hdr first = *h;

	if (!x)
		return;
	first.flags = x->hflags;
	dispatch(srv, c, &first, x->fixed, x->fixed_len, x->buf, x->total, x);
}

/* An admitted command to where it is handled. */
static void run_command(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(h->code);

	if (h->flags & MBX_F_CHUNKED)
		run_chunk(srv, c, h, p);
	else if (ci->flags & MBX_CI_SERVER)
		srv_handle_protocol(srv, c, h, p);
	else if (ci->flags & MBX_CI_DATA)
		dispatch(srv, c, h, p, ci->fixed, p + ci->fixed, h->len - ci->fixed, NULL);
	else
		dispatch(srv, c, h, p, h->len, NULL, 0, NULL);
}

void srv_handle_msg(mbx_server *srv, const uint8_t *buf, size_t n)
{
	mbx_hdr h;
	mbx_bad bad = MBX_BAD_NONE;
	const uint8_t *p = buf + MBX_HDR_SIZE;
	int rc = check_header(srv, buf, n, &h, &bad);
	mbx_client *c;

	if (rc == 0 && h.code == MBX_CMD_REGISTER) {
		rc = mbx_cmd_validate(&h, p, &bad);
		if (rc) {
			srv_count_bad(srv, bad); /* no queue to answer to */
			srv->stats.reg_refused++;
		} else {
			srv_handle_register(srv, &h, p);
		}
		return;
	}
	c = sender_of(srv, &h, bad);
	if (rc) {
		srv_count_bad(srv, bad);
		if (c && !(h.flags & MBX_F_NO_REPLY))
			srv_send_status(srv, c, h.code, h.corr, rc, 0, NULL, 0);
		return;
	}
	if (!c) {
		srv_count_bad(srv, MBX_BAD_CLIENT);
		return;
	}
	c->confirmed = true;
	srv_lease_renew(srv, c, srv->now_us);
	if (discarded(c, &h) || admit(srv, c, &h, p) != 0)
		return;
	run_command(srv, c, &h, p);
}
