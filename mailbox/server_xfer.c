/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_xfer.c - transfers and chunking (docs/mailbox.md
 * "Chunking"): the transfer slots, their budget and limits, the
 * reassembly of a chunked command, the flow-controlled stream of an answer
 * larger than one message, and the slots' time-outs.
 */
#include "mailbox/server_int.h"

#include <errno.h>
#include <string.h>

/* End a transfer: its budget goes back now; its pages too, unless the
 * caller still reads the buffer (mbx_server_respond: an answer may live in
 * the request's data) and gives them back itself once it is copied. */
void srv_xfer_end(mbx_server *srv, mbx_xfer *x, bool keep_pages)
{
	uint8_t *buf = x->buf;
	size_t touched = x->touched;

	mbx_budget_give(srv->cfg.budget, x->reserved);
	memset(x, 0, sizeof *x);
	x->buf = buf;
	x->touched = touched;
	if (!keep_pages && x->touched > MBX_BUFFER_KEEP) {
		mbx_buffer_release(x->buf, x->touched);
		x->touched = MBX_BUFFER_KEEP;
	}
}

void srv_xfer_free(mbx_server *srv, mbx_xfer *x)
{
	srv_xfer_end(srv, x, false);
}

/* Mark bytes [0, n) of the slot's buffer as about to be written. */
static void xfer_touch(mbx_xfer *x, size_t n)
{
	if (n > x->touched)
		x->touched = n;
}

mbx_xfer *srv_xfer_find(mbx_server *srv, uint32_t client, uint64_t corr, xfer_state st)
{
	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		if (x->st == st && x->client == client && x->corr == corr)
			return x;
	}
	return NULL;
}

/* The first free slot (or NULL); the slots in use by c (*mine) and by
 * read-only clients (*readers). */
static mbx_xfer *slot_census(mbx_server *srv, const mbx_client *c, unsigned *mine,
			     unsigned *readers)
{
	mbx_xfer *free_slot = NULL;

	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		if (x->st == XS_FREE) {
			if (!free_slot)
				free_slot = x;
			continue;
		}
		if (x->client == c->id)
			(*mine)++;
		const mbx_client *o = srv_client_find(srv, x->client);

		if (o && o->access < MBX_ACCESS_WRITE)
			(*readers)++;
	}
	return free_slot;
}

/* A free transfer slot for client c and a transfer of size bytes, or NULL
 * with *status: a client holds at most xfer_per_client slots, and
 * read-only clients together leave one slot to writers (a reader that
 * never acknowledges its big answers must not make a writer's download
 * fail with BUSY) - MBX_E_BUSY; the size must fit the transfer memory
 * budget of all lines - MBX_E_NO_MEMORY. A refusal by a limit or by the
 * budget is counted here, the failed transfer by the caller. */
static mbx_xfer *xfer_alloc(mbx_server *srv, const mbx_client *c, size_t size, int *status)
{
	unsigned mine = 0, readers = 0;
	mbx_xfer *free_slot = slot_census(srv, c, &mine, &readers);

	*status = MBX_E_BUSY;
	if (free_slot && (mine >= srv->cfg.xfer_per_client ||
			  (c->access < MBX_ACCESS_WRITE && srv->cfg.xfer_slots > 1 &&
			   readers + 1 >= srv->cfg.xfer_slots))) {
		srv->stats.limited++;
		free_slot = NULL;
	}
	/* read-only clients leave one max_transfer of the budget to writers */
	if (free_slot &&
	    !mbx_budget_take(srv->cfg.budget, size,
			     c->access < MBX_ACCESS_WRITE ? srv->cfg.max_transfer : 0)) {
		*status = MBX_E_NO_MEMORY;
		srv->stats.budget_refused++;
		free_slot = NULL;
	}
	if (!free_slot)
		return NULL; /* the caller counts the failed transfer */
	*status = 0;
	free_slot->reserved = size;
	free_slot->end_us = srv->now_us + (uint64_t)srv->cfg.xfer_max_ms * 1000u;
	return free_slot;
}

size_t srv_chunk_size(const mbx_client *c)
{
	return c->resp_msg - MBX_HDR_SIZE;
}

/* At most this many chunks unacknowledged in the client's response queue:
 * half of it, so answers to other requests still find room. */
static unsigned stream_window(const mbx_client *c)
{
	unsigned w = c->resp_depth / 2;

	return w ? w : 1;
}

/* Push chunks of an outgoing transfer while the window and the queue
 * allow. */
void srv_xfer_pump(mbx_server *srv, mbx_xfer *x)
{
	mbx_client *c = srv_client_find(srv, x->client);
	size_t csz;

	if (!c) {
		srv_xfer_free(srv, x);
		return;
	}
	csz = srv_chunk_size(c);
	x->retry_us = 0;
	while (x->done < x->total) {
		size_t n = x->total - x->done;
		int rc;

		if ((unsigned)(x->next_chunk - x->acked) >= stream_window(c))
			return; /* wait for XFER_ACK */
		if (n > csz)
			n = csz;
		mbx_hdr h = {
			.code = x->code,
			.corr = x->corr,
			.status = x->status,
			.abort = x->abort,
			.flags = MBX_F_CHUNKED | (x->done + n < x->total ? MBX_F_MORE : 0),
			.chunk = x->next_chunk,
			.total = (uint32_t)x->total,
		};
		rc = srv_send_to(srv, c, false, &h, x->buf + x->done, n, SEND_STREAM);
		if (rc == -EAGAIN) {
			x->retry_us = srv->now_us + RETRY_US;
			return;
		}
		if (rc < 0) {
			srv->stats.xfer_failed++;
			srv_xfer_free(srv, x);
			return;
		}
		x->done += n;
		x->next_chunk++;
		x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
	}
	srv->stats.xfer_out++;
	srv_xfer_free(srv, x);
}

/* The rest of the transfer h begins (when more chunks follow) is ignored,
 * and the client told why unless it asked for no reply. */
static void refuse_chunks(mbx_server *srv, mbx_client *c, const mbx_hdr *h, int status)
{
	if (h->flags & MBX_F_MORE) {
		c->discarding = true;
		c->discard_corr = h->corr;
	}
	if (!(h->flags & MBX_F_NO_REPLY))
		srv_send_status(srv, c, h->code, h->corr, status, 0, NULL, 0);
}

static void refuse_transfer(mbx_server *srv, mbx_client *c, const mbx_hdr *h, int status)
{
	srv->stats.xfer_failed++;
	refuse_chunks(srv, c, h, status);
}

/* The first chunk of a command: a slot for the whole transfer. */
static void chunk_first(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(h->code);
	mbx_xfer *x;
	int st;

	if (h->total > srv->cfg.max_transfer) {
		refuse_transfer(srv, c, h, MBX_E_TOO_BIG);
		return;
	}
	if (srv_xfer_find(srv, c->id, h->corr, XS_IN)) {
		srv_count_bad(srv, MBX_BAD_SEQUENCE);
		refuse_transfer(srv, c, h, MBX_E_SEQUENCE);
		return;
	}
	x = xfer_alloc(srv, c, h->total, &st);
	if (!x) {
		refuse_transfer(srv, c, h, st);
		return;
	}
	x->st = XS_IN;
	x->client = c->id;
	x->corr = h->corr;
	x->code = h->code;
	x->hflags = h->flags;
	x->fixed_len = ci->fixed;
	memcpy(x->fixed, p, ci->fixed);
	x->total = h->total;
	x->done = h->len - ci->fixed;
	xfer_touch(x, x->total);
	memcpy(x->buf, p + ci->fixed, x->done);
	x->next_chunk = 1;
	x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
}

/* A later chunk that does not continue x (NULL: no transfer) as announced. */
static bool chunk_out_of_step(const mbx_xfer *x, const mbx_hdr *h)
{
	return !x || x->code != h->code || x->next_chunk != h->chunk || x->total != h->total ||
	       x->done + h->len > x->total ||
	       (!(h->flags & MBX_F_MORE) && x->done + h->len != x->total);
}

mbx_xfer *srv_chunk_in(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_xfer *x;

	if (h->chunk == 0) {
		chunk_first(srv, c, h, p);
		return NULL;
	}
	x = srv_xfer_find(srv, c->id, h->corr, XS_IN);
	if (chunk_out_of_step(x, h)) {
		srv_count_bad(srv, MBX_BAD_SEQUENCE);
		if (x) {
			srv->stats.xfer_failed++;
			srv_xfer_free(srv, x);
		}
		refuse_chunks(srv, c, h, MBX_E_SEQUENCE);
		return NULL;
	}
	memcpy(x->buf + x->done, p, h->len);
	x->done += h->len;
	x->next_chunk++;
	x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
	if (h->flags & MBX_F_MORE)
		return NULL;
	srv->stats.xfer_in++;
	x->st = XS_HELD;
	return x;
}

/* A transfer that stalled or outlived its lifetime fails: the client of a
 * command still sending is told, one waiting for an answer learns it lost
 * one (the overflow notice). */
static void xfer_expire(mbx_server *srv, mbx_xfer *x)
{
	mbx_client *c = srv_client_find(srv, x->client);

	srv->stats.xfer_failed++;
	srv->stats.xfer_expired++;
	if (c && x->st == XS_IN && !(x->hflags & MBX_F_NO_REPLY))
		srv_send_status(srv, c, x->code, x->corr, MBX_E_TIMEOUT, 0, NULL, 0);
	else if (c) /* an answer was lost: tell the client */
		c->drop_resp++;
	srv_xfer_free(srv, x);
}

uint64_t srv_xfers_tick(mbx_server *srv, uint64_t now_us)
{
	uint64_t next = UINT64_MAX;

	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		if (x->st != XS_IN && x->st != XS_OUT)
			continue;
		if (now_us >= x->deadline_us || now_us >= x->end_us) {
			xfer_expire(srv, x);
			continue;
		}
		if (x->st == XS_OUT && x->retry_us && now_us >= x->retry_us)
			srv_xfer_pump(srv, x);
		if (x->st == XS_FREE)
			continue;
		next = min64(next, min64(x->deadline_us, x->end_us));
		if (x->st == XS_OUT && x->retry_us)
			next = min64(next, x->retry_us);
	}
	return next;
}

int srv_stream_answer(mbx_server *srv, mbx_client *c, const mbx_reply_to *to, int status,
		      uint32_t abort, const void *payload, size_t len)
{
	size_t nchunks;
	mbx_xfer *x;
	int st;

	nchunks = (len + srv_chunk_size(c) - 1) / srv_chunk_size(c);
	if (len > srv->cfg.max_transfer || nchunks > 0xFFFFu) {
		srv->stats.xfer_failed++;
		srv_send_status(srv, c, to->code, to->corr, MBX_E_TOO_BIG, 0, NULL, 0);
		return -EMSGSIZE;
	}
	x = xfer_alloc(srv, c, len, &st);
	if (!x) {
		srv->stats.xfer_failed++;
		srv_send_status(srv, c, to->code, to->corr, st, 0, NULL, 0);
		return -EBUSY;
	}
	x->st = XS_OUT;
	x->client = c->id;
	x->corr = to->corr;
	x->code = to->code;
	x->status = status;
	x->abort = abort;
	xfer_touch(x, len);
	memmove(x->buf, payload, len);
	x->total = len;
	x->done = 0;
	x->next_chunk = 0;
	x->acked = 0;
	x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
	srv_xfer_pump(srv, x);
	return 0;
}
