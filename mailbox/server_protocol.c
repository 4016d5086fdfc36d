/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_protocol.c - the commands the mailbox answers itself
 * (UNREGISTER, SUBSCRIBE, UNSUBSCRIBE, PING, XFER_ACK, MBX_STATS; REGISTER
 * is server_register.c's): one function each, and srv_handle_protocol() that
 * picks it. A new protocol command is one more function here.
 */
#include "mailbox/server_int.h"

#include <string.h>

/* The answer to a protocol command, unless the client asked for none. */
static void protocol_reply(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const void *payload,
			   size_t len)
{
	if (!(h->flags & MBX_F_NO_REPLY))
		srv_send_status(srv, c, h->code, h->corr, 0, 0, payload, len);
}

static void subscribe(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_subscribe_req r;
	mbx_subscribe_resp out;

	memcpy(&r, p, sizeof r);
	c->classes |= r.classes & MBX_EVC_ALL;
	if (r.classes & MBX_EVC_RAW) {
		c->n_filters = r.n_filters;
		memcpy(c->filters, r.filters, sizeof c->filters);
	}
	srv_sub_index_update(srv, c);
	out.classes = c->classes | MBX_EVC_OVERFLOW;
	protocol_reply(srv, c, h, &out, sizeof out);
}

static void unsubscribe(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_unsubscribe_req r;
	mbx_subscribe_resp out;

	memcpy(&r, p, sizeof r);
	c->classes &= ~r.classes;
	if (r.classes & MBX_EVC_RAW) {
		c->n_filters = 0;
		memset(c->filters, 0, sizeof c->filters);
	}
	srv_sub_index_update(srv, c);
	out.classes = c->classes | MBX_EVC_OVERFLOW;
	protocol_reply(srv, c, h, &out, sizeof out);
}

static void xfer_ack(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_xfer_ack r;
	mbx_xfer *x = srv_xfer_find(srv, c->id, h->corr, XS_OUT);

	memcpy(&r, p, sizeof r);
	/* An ack for a finished transfer is normal (the last chunks
	 * raced it); an ack beyond what was sent is ignored. */
	if (x && r.next_chunk > x->acked && r.next_chunk <= x->next_chunk) {
		x->acked = r.next_chunk;
		srv_xfer_pump(srv, x);
	}
}

static void mailbox_stats(mbx_server *srv, mbx_client *c, const mbx_hdr *h)
{
	mbx_stats_wire out = {
		.commands_ok = srv->stats.commands_ok,
		.malformed = srv->stats.malformed_total,
		.access_denied = srv->stats.access_denied,
		.events_sent = srv->stats.events_sent,
		.responses_sent = srv->stats.responses_sent,
		.dropped = srv->stats.dropped,
		.clients_registered = srv->stats.clients_registered,
		.clients_reaped = srv->stats.clients_reaped,
		.clients = srv->stats.clients,
		.xfer_failed = srv->stats.xfer_failed,
		.xfer_expired = srv->stats.xfer_expired,
		.limited = srv->stats.limited,
		/* the budget is one for all lines: so are its counts
		 * (SDO uploads of the lines included) */
		.budget_refused = srv->cfg.budget ? atomic_load(&srv->cfg.budget->refused)
						  : srv->stats.budget_refused,
		.budget_used = mbx_budget_used(srv->cfg.budget),
		.late_wakes = srv->stats.late_wakes,
		.reg_refused = srv->stats.reg_refused,
		.reg_unanswered = srv->stats.reg_unanswered,
	};
	protocol_reply(srv, c, h, &out, sizeof out);
}

void srv_handle_protocol(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	srv->stats.commands_ok++;
	switch (h->code) {
	case MBX_CMD_UNREGISTER:
		protocol_reply(srv, c, h, NULL, 0);
		srv_client_remove(srv, c, false);
		return;
	case MBX_CMD_SUBSCRIBE:
		subscribe(srv, c, h, p);
		return;
	case MBX_CMD_UNSUBSCRIBE:
		unsubscribe(srv, c, h, p);
		return;
	case MBX_CMD_PING: {
		mbx_ping_resp out = { .lease_ms = srv->cfg.lease_ms, .now_us = srv->now_us };

		protocol_reply(srv, c, h, &out, sizeof out);
		return;
	}
	case MBX_CMD_XFER_ACK:
		xfer_ack(srv, c, h, p);
		return;
	case MBX_CMD_MBX_STATS:
		mailbox_stats(srv, c, h);
		return;
	}
}
