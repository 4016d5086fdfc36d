/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_send.c - the bottom of the server: finding a registered
 * client, and sending one message to its response or event queue without
 * ever blocking (a full queue drops and counts the message, and the next
 * one that gets through carries the count: docs/mailbox.md "Overflow").
 */
#include "mailbox/server_int.h"

#include <errno.h>
#include <mqueue.h>

mbx_client *srv_client_find(const mbx_server *srv, uint32_t id)
{
	uint32_t idx = (id & 0xFFFFu);

	if (id == 0 || idx == 0 || idx > srv->cfg.max_clients)
		return NULL;
	mbx_client *c = &srv->clients[idx - 1];

	return c->id == id ? c : NULL;
}

void srv_count_bad(mbx_server *srv, mbx_bad b)
{
	if (b >= MBX_BAD_COUNT)
		b = MBX_BAD_NONE;
	srv->stats.malformed[b]++;
	srv->stats.malformed_total++;
}

/* Send the message encoded in srv->tx (n bytes) to a client's response
 * or event queue, without blocking, readdressed to it (id, and the count
 * of its messages lost before this one). Returns 0, -EAGAIN (stream: queue
 * full), -ENOBUFS (dropped), -EPIPE (queue unusable: client marked dead). */
int srv_deliver(mbx_server *srv, mbx_client *c, bool event, size_t n, enum send_mode mode)
{
	uint32_t *pending = event ? &c->drop_evt : &c->drop_resp;

	mbx_hdr_set_recipient(srv->tx, c->id, *pending);
	if (mq_send(event ? c->evt : c->resp, (const char *)srv->tx, n, 0) == 0) {
		*pending = 0;
		if (event)
			srv->stats.events_sent++;
		else
			srv->stats.responses_sent++;
		return 0;
	}
	if (errno == EAGAIN) {
		if (mode == SEND_STREAM)
			return -EAGAIN;
		(*pending)++;
		c->dropped++;
		srv->stats.dropped++;
		return -ENOBUFS;
	}
	/* EBADF & co: the descriptor is unusable; reap at the next tick */
	c->dead = true;
	return -EPIPE;
}

/* Encode one message into srv->tx (addressed to nobody yet). */
int srv_encode(mbx_server *srv, bool event, mbx_hdr *h, const void *payload, size_t len)
{
	h->magic = MBX_MAGIC;
	h->version = MBX_VERSION;
	h->kind = event ? MBX_KIND_EVENT : MBX_KIND_RESPONSE;
	h->line = srv->cfg.line;
	h->client = 0;
	h->token = 0;
	h->flags &= (uint8_t)~MBX_F_OVERFLOW;
	h->dropped = 0;
	return mbx_msg_build(srv->tx, MBX_MSG_MAX, h, payload, len);
}

/* Send one message to a client's response or event queue, without
 * blocking: srv_encode + srv_deliver. */
int srv_send_to(mbx_server *srv, mbx_client *c, bool event, mbx_hdr *h, const void *payload,
		size_t len, enum send_mode mode)
{
	int n = srv_encode(srv, event, h, payload, len);

	if (n < 0 || (size_t)n > (event ? c->evt_msg : c->resp_msg))
		return -EMSGSIZE;
	return srv_deliver(srv, c, event, (size_t)n, mode);
}

int srv_send_status(mbx_server *srv, mbx_client *c, uint16_t code, uint64_t corr, int status,
		    uint32_t abort, const void *payload, size_t len)
{
	mbx_hdr h = { .code = code, .corr = corr, .status = status, .abort = abort };

	return srv_send_to(srv, c, false, &h, payload, len, SEND_NORMAL);
}
