/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_events.c - event fan-out: the index of subscribers by
 * class, one encoding of an event for all of them (raw frames through each
 * client's filters), an event to one client, and the overflow notice that
 * tells a client what it lost.
 */
#include "mailbox/server_int.h"

#include <errno.h>
#include <string.h>

/* Keep the class index of client c in step with c->classes (and c->id:
 * a free slot subscribes to nothing). */
void srv_sub_index_update(mbx_server *srv, const mbx_client *c)
{
	size_t slot = (size_t)(c - srv->clients);
	uint64_t bit = 1ull << (slot % 64);

	for (unsigned b = 0; b < 32; b++) {
		uint64_t *w = &srv->sub_bits[b * srv->sub_words + slot / 64];

		if (c->id && (c->classes & (1u << b)))
			*w |= bit;
		else
			*w &= ~bit;
	}
}

/* A subscriber of the class: does a raw frame pass its filters? */
static bool raw_passes(const mbx_client *c, uint32_t cls, const uint8_t *payload, size_t len)
{
	mbx_ev_raw raw;

	if (cls != MBX_EVC_RAW || c->n_filters == 0)
		return true;
	if (len < sizeof raw)
		return false;
	memcpy(&raw, payload, sizeof raw);
	for (unsigned i = 0; i < c->n_filters; i++)
		if (mbx_raw_filter_match(&c->filters[i], &raw.frame))
			return true;
	return false;
}

/* The event in srv->tx (n bytes, payload len) to one client. */
static bool publish_to(mbx_server *srv, mbx_client *c, uint32_t cls, size_t n, size_t len)
{
	const uint8_t *payload = srv->tx + MBX_HDR_SIZE;

	if (!c->id || c->dead || !raw_passes(c, cls, payload, len))
		return false;
	if (len > c->evt_msg - MBX_HDR_SIZE) {
		/* cannot fit this client's queue: lost, counted, flagged */
		c->drop_evt++;
		c->dropped++;
		srv->stats.dropped++;
		return false;
	}
	return srv_deliver(srv, c, true, n, SEND_NORMAL) == 0;
}

/* Encoded once for all; the recipients are the set bits of the class's
 * index (every client for an overflow notice). */
int mbx_server_publish(mbx_server *srv, uint16_t ev_code, uint64_t corr, const void *payload,
		       size_t len)
{
	uint32_t cls = mbx_event_class_of(ev_code);
	mbx_hdr h = { .code = ev_code, .corr = corr };
	int reached = 0, n;

	if (!cls || (len && !payload))
		return -EINVAL;
	if (len > MBX_MSG_MAX - MBX_HDR_SIZE)
		return -EMSGSIZE;
	n = srv_encode(srv, true, &h, payload, len);
	if (n < 0)
		return n;
	if (cls == MBX_EVC_OVERFLOW) {
		for (unsigned i = 0; i < srv->cfg.max_clients; i++)
			reached += publish_to(srv, &srv->clients[i], cls, (size_t)n, len);
		return reached;
	}
	const uint64_t *words = &srv->sub_bits[(unsigned)__builtin_ctz(cls) * srv->sub_words];

	for (size_t w = 0; w < srv->sub_words; w++) {
		for (uint64_t bits = words[w]; bits; bits &= bits - 1) {
			size_t slot = w * 64 + (size_t)__builtin_ctzll(bits);

			reached += publish_to(srv, &srv->clients[slot], cls, (size_t)n, len);
		}
	}
	return reached;
}

int mbx_server_notify(mbx_server *srv, const mbx_reply_to *to, uint16_t ev_code,
		      const void *payload, size_t len)
{
	mbx_client *c = srv_client_find(srv, to->client);
	mbx_hdr h = { .code = ev_code, .corr = to->corr };
	int rc;

	if (!c)
		return -ENOENT;
	if (!mbx_event_class_of(ev_code))
		return -EINVAL;
	if (len > c->evt_msg - MBX_HDR_SIZE) {
		/* Never cut an event short (an SDO_DONE used to be truncated
		 * to whatever fitted): it cannot reach this client, which is
		 * counted and flagged like any other lost event. */
		c->drop_evt++;
		c->dropped++;
		srv->stats.dropped++;
		return -EMSGSIZE;
	}
	rc = srv_send_to(srv, c, true, &h, payload, len, SEND_NORMAL);
	return rc == -EPIPE ? -ENOENT : rc;
}

unsigned mbx_server_subscribers(const mbx_server *srv, uint32_t cls)
{
	unsigned n = 0;

	if (!cls || (cls & (cls - 1)) || cls == MBX_EVC_OVERFLOW)
		return cls == MBX_EVC_OVERFLOW ? (unsigned)srv->stats.clients : 0;
	const uint64_t *words = &srv->sub_bits[(unsigned)__builtin_ctz(cls) * srv->sub_words];

	for (size_t w = 0; w < srv->sub_words; w++)
		n += (unsigned)__builtin_popcountll(words[w]);
	return n;
}

bool srv_overflow_notice(mbx_server *srv, mbx_client *c)
{
	mbx_ev_overflow ov = { .dropped_events = c->drop_evt, .dropped_responses = c->drop_resp };
	mbx_hdr h = { .code = MBX_EV_OVERFLOW };
	uint32_t dr = c->drop_resp;

	if (srv_send_to(srv, c, true, &h, &ov, sizeof ov, SEND_STREAM) != 0)
		return false;
	c->drop_resp -= dr;
	return true;
}
