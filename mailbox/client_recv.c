/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_recv.c - reading libcogw's response queue: the leader's
 * receive (one message, up to a deadline), and what an answer does: it
 * completes a waiting call (chunks reassembled into its buffer), an
 * asynchronous request (into a heap buffer, queued in the ring for
 * cogw_recv()), or the helper thread's re-registration; the XFER_ACK it
 * asks for is sent after it. Needs no thread of its own: whoever leads
 * calls it.
 */
#include "mailbox/client_transport.h"

#include <errno.h>
#include <mqueue.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct ack_todo {
	bool needed;
	unsigned line;
	uint64_t corr;
	uint16_t next_chunk;
	/* the answer to a re-registration the reader thread sent */
	bool rereg;
	int rereg_status;
	mbx_register_resp rereg_resp;
} ack_todo;

void client_ring_push(cogw *h, cogw_msg *m)
{
	uint64_t one = 1;

	if (h->ring_count == ASYNC_RING) {
		h->stats.async_dropped++;
		free(m->data);
		return;
	}
	h->ring[(h->ring_head + h->ring_count) % ASYNC_RING] = *m;
	h->ring_count++;
	if (h->efd_set || h->loop_taking)
		return; /* readable already (one write per non-empty spell), or
	                 * popped by the loop's receive at once */
	h->efd_set = true;
	if (write(h->efd, &one, sizeof one) < 0) {
		/* counter saturated: it is readable anyway */
	}
}

async_op *client_async_add(cogw *h, unsigned line, uint16_t cmd, uint64_t id, uint64_t deadline_us)
{
	async_op *a = calloc(1, sizeof *a);

	if (!a)
		return NULL;
	a->corr = id;
	a->line = (uint8_t)line;
	a->code = cmd;
	a->deadline_us = deadline_us;
	pthread_mutex_lock(&h->mu);
	a->next = h->asyncs;
	h->asyncs = a;
	pthread_cond_signal(&h->reader_cond); /* its answer needs a reader */
	if (h->evt_waiters)                   /* its answer will not come on the event queue */
		mq_send(h->evt_self, "", 0, 0);
	pthread_mutex_unlock(&h->mu);
	return a;
}

void client_async_drop(cogw *h, async_op *a)
{
	pthread_mutex_lock(&h->mu);
	for (async_op **pp = &h->asyncs; *pp; pp = &(*pp)->next) {
		if (*pp == a) {
			*pp = a->next;
			free(a->data);
			free(a);
			break;
		}
	}
	pthread_mutex_unlock(&h->mu);
}

bool client_ring_pop(cogw *h, cogw_msg *m)
{
	bool got = false;
	uint64_t v;

	pthread_mutex_lock(&h->mu);
	if (h->ring_count) {
		*m = h->ring[h->ring_head];
		h->ring_head = (h->ring_head + 1) % ASYNC_RING;
		h->ring_count--;
		got = true;
	}
	if (!h->ring_count && h->efd_set) {
		h->efd_set = false;
		if (read(h->efd, &v, sizeof v) < 0) {
			/* already zero */
		}
	}
	pthread_mutex_unlock(&h->mu);
	return got;
}

/* One event from the event queue, waiting until until_us (monotonic; 0:
 * not at all); 1 = got one, 0 = none, < 0 error. */
int client_event_pop(cogw *h, cogw_msg *m, uint8_t *buf, uint64_t now, uint64_t until_us)
{
	for (;;) {
		struct timespec at = realtime_deadline(now, until_us);
		ssize_t n = mq_timedreceive(h->evt, (char *)buf, h->evt_msg, NULL, &at);
		mbx_hdr hd;

		if (n < 0)
			return errno == ETIMEDOUT || errno == EAGAIN || errno == EINTR
				       ? 0
				       : COGW_E_SYSTEM;
		if (n == 0)
			return 0; /* a wake-up: an async answer is due, or a stretched slice */
		if (mbx_hdr_decode(buf, (size_t)n, &hd, NULL) < 0 || hd.kind != MBX_KIND_EVENT ||
		    mbx_event_validate(hd.code, buf + MBX_HDR_SIZE, hd.len) < 0) {
			pthread_mutex_lock(&h->mu);
			h->stats.stray_responses++;
			pthread_mutex_unlock(&h->mu);
			continue;
		}
		if (hd.flags & MBX_F_OVERFLOW) {
			pthread_mutex_lock(&h->mu);
			h->stats.overflow_flags++;
			h->stats.dropped_reported += hd.dropped;
			pthread_mutex_unlock(&h->mu);
		}
		*m = (cogw_msg){ .kind = MBX_KIND_EVENT,
				 .line = hd.line,
				 .code = hd.code,
				 .abort = hd.abort,
				 .corr = hd.corr,
				 .dropped = hd.dropped,
				 .len = hd.len };
		m->data = malloc(hd.len ? hd.len : 1);
		if (!m->data)
			return COGW_E_NOMEM;
		memcpy(m->data, buf + MBX_HDR_SIZE, hd.len);
		return 1;
	}
}

static unsigned ack_every(const cogw *h)
{
	unsigned w = h->resp_depth / 2;

	w = w ? w : 1;
	return w / 2 ? w / 2 : 1;
}

static void want_ack(cogw *h, const mbx_hdr *hd, uint16_t next, ack_todo *ack)
{
	if ((hd->flags & MBX_F_MORE) && next % ack_every(h) == 0) {
		ack->needed = true;
		ack->line = hd->line;
		ack->corr = hd->corr;
		ack->next_chunk = next;
	}
}

/* Returns true when the waiter is complete. */
static bool feed_waiter(cogw *h, waiter *w, const mbx_hdr *hd, const uint8_t *p, ack_todo *ack)
{
	w->status = hd->status;
	w->abort = hd->abort;
	if (!(hd->flags & MBX_F_CHUNKED)) {
		if (w->cap && hd->len)
			memcpy(w->buf, p, hd->len < w->cap ? hd->len : w->cap);
		w->len = hd->len;
		return true;
	}
	if (hd->chunk != w->next_chunk) {
		w->status = COGW_E_SEQUENCE; /* a chunk was lost */
		return true;
	}
	if (w->len < w->cap)
		memcpy(w->buf + w->len, p, w->cap - w->len < hd->len ? w->cap - w->len : hd->len);
	w->len += hd->len;
	w->next_chunk++;
	want_ack(h, hd, w->next_chunk, ack);
	if (hd->flags & MBX_F_MORE)
		return false;
	if (w->len != hd->total)
		w->status = COGW_E_SEQUENCE;
	return true;
}

static void feed_async(cogw *h, async_op **pp, const mbx_hdr *hd, const uint8_t *p, ack_todo *ack)
{
	async_op *a = *pp;
	bool done = true;

	a->status = hd->status;
	a->abort = hd->abort;
	if (hd->flags & MBX_F_OVERFLOW)
		a->dropped += hd->dropped;
	if (hd->flags & MBX_F_CHUNKED) {
		if (!a->data) {
			a->total = hd->total;
			a->data = malloc(a->total ? a->total : 1);
			if (!a->data)
				a->status = COGW_E_NOMEM;
		}
		if (hd->chunk != a->next_chunk || hd->total != a->total ||
		    a->len + hd->len > a->total) {
			a->status = COGW_E_SEQUENCE;
		} else if (a->data) {
			memcpy(a->data + a->len, p, hd->len);
			a->len += hd->len;
			a->next_chunk++;
			want_ack(h, hd, a->next_chunk, ack);
			done = !(hd->flags & MBX_F_MORE);
		}
	} else {
		a->data = malloc(hd->len ? hd->len : 1);
		if (a->data) {
			memcpy(a->data, p, hd->len);
			a->len = hd->len;
		} else {
			a->status = COGW_E_NOMEM;
		}
	}
	if (!done)
		return;
	cogw_msg m = {
		.kind = MBX_KIND_RESPONSE,
		.line = a->line,
		.code = a->code,
		.status = a->status,
		.abort = a->abort,
		.corr = a->corr,
		.dropped = a->dropped,
		.len = a->status ? 0 : a->len,
		.data = a->data,
	};
	*pp = a->next;
	free(a);
	client_ring_push(h, &m);
}

/* The answer to a re-registration the helper thread sent: kept in ack,
 * applied after the message (reregister_done). */
static void take_rereg(const mbx_hdr *hd, const uint8_t *p, ack_todo *ack)
{
	ack->rereg = true;
	ack->line = hd->line;
	ack->corr = hd->corr;
	ack->rereg_status = hd->len == sizeof ack->rereg_resp ? hd->status : COGW_E_PROTOCOL;
	if (hd->len == sizeof ack->rereg_resp)
		memcpy(&ack->rereg_resp, p, sizeof ack->rereg_resp);
}

static void waiter_fed(cogw *h, waiter *w, const mbx_hdr *hd, const uint8_t *p, ack_todo *ack)
{
	if (feed_waiter(h, w, hd, p, ack)) {
		w->done = true;
		pthread_cond_broadcast(&h->cond);
	}
}

/* A waiting call or an asynchronous request with the answer's
 * correlation id takes it: true when one did. */
static bool feed_by_corr(cogw *h, const mbx_hdr *hd, const uint8_t *p, ack_todo *ack)
{
	for (waiter *w = h->waiters; w; w = w->next) {
		if (w->corr == hd->corr && !w->done) {
			waiter_fed(h, w, hd, p, ack);
			return true;
		}
	}
	for (async_op **pp = &h->asyncs; *pp; pp = &(*pp)->next) {
		if ((*pp)->corr == hd->corr) {
			feed_async(h, pp, hd, p, ack);
			return true;
		}
	}
	return false;
}

/* A line answers a registration of our queues again, under the corr of
 * whichever REGISTER named them, at most every 100 ms: ours may have gone
 * unanswered (docs/mailbox.md "Security model"). True when a waiting
 * REGISTER of that line took it. */
static bool feed_register_again(cogw *h, const mbx_hdr *hd, const uint8_t *p, ack_todo *ack)
{
	if (hd->code != MBX_CMD_REGISTER || hd->status != 0)
		return false;
	for (waiter *w = h->waiters; w; w = w->next) {
		if (w->code == MBX_CMD_REGISTER && w->line == hd->line && !w->done &&
		    feed_waiter(h, w, hd, p, ack)) {
			w->done = true;
			pthread_cond_broadcast(&h->cond);
			return true;
		}
	}
	return false;
}

static void handle_response(cogw *h, const uint8_t *buf, size_t n, ack_todo *ack)
{
	mbx_hdr hd;
	const uint8_t *p = buf + MBX_HDR_SIZE;

	if (mbx_hdr_decode(buf, n, &hd, NULL) < 0 || hd.kind != MBX_KIND_RESPONSE) {
		h->stats.stray_responses++;
		return;
	}
	if (hd.flags & MBX_F_OVERFLOW) {
		h->stats.overflow_flags++;
		h->stats.dropped_reported += hd.dropped;
	}
	if ((hd.corr & REREG_CORR_BIT) && hd.code == MBX_CMD_REGISTER)
		take_rereg(&hd, p, ack);
	else if (!feed_by_corr(h, &hd, p, ack) && !feed_register_again(h, &hd, p, ack))
		h->stats.stray_responses++;
}

static void reregister_done(cogw *h, const ack_todo *t)
{
	line_state *ls;
	mbx_subscribe_req sub;

	if (t->line >= MBX_LINES_MAX)
		return;
	ls = &h->lines[t->line];
	pthread_mutex_lock(&h->setup_mu);
	if (ls->rereg_corr != t->corr) {
		pthread_mutex_unlock(&h->setup_mu);
		return;
	}
	ls->rereg_corr = 0;
	ls->registering = false;
	if (t->rereg_status == 0)
		client_line_registered(ls, &t->rereg_resp, mono_us());
	sub = (mbx_subscribe_req){ .classes = ls->sub_classes, .n_filters = ls->n_filters };
	memcpy(sub.filters, ls->filters, sizeof sub.filters);
	pthread_cond_broadcast(&h->setup_cond);
	pthread_mutex_unlock(&h->setup_mu);
	if (t->rereg_status == 0)
		client_send_cmd(h, t->line, MBX_CMD_SUBSCRIBE, MBX_F_NO_REPLY, 0, &sub, sizeof sub,
				NULL, 0, mono_us() + 100000u);
}

/* After a message: the XFER_ACK it asked for, the re-registration it
 * answered. Called without h->mu. */
static void after_response(cogw *h, const ack_todo *ack)
{
	if (ack->needed) {
		mbx_xfer_ack a = { .next_chunk = ack->next_chunk };

		client_send_cmd(h, ack->line, MBX_CMD_XFER_ACK, 0, ack->corr, &a, sizeof a, NULL, 0,
				mono_us() + 1000000u);
	}
	if (ack->rereg)
		reregister_done(h, ack);
}

/* The leader (h->leader set by the caller, h->mu not held): receive one
 * message from the response queue, waiting until until_us (monotonic) at
 * most, and handle it. Returns 1 a message, 0 none (timeout, signal, a
 * wake-up), -1 the queue is unusable. */
int client_lead_read(cogw *h, uint64_t now, uint64_t until_us)
{
	struct timespec at = realtime_deadline(now, until_us);
	ack_todo ack = { 0 };
	ssize_t n;

	n = mq_timedreceive(h->resp, (char *)h->lead_buf, h->resp_msg, NULL, &at);
	if (n < 0)
		return errno == ETIMEDOUT || errno == EINTR ? 0 : -1;
	if (n == 0)
		return 0; /* a wake-up (close, or a slice stretched by a clock step) */
	pthread_mutex_lock(&h->mu);
	if (!h->closing)
		handle_response(h, h->lead_buf, (size_t)n, &ack);
	pthread_mutex_unlock(&h->mu);
	after_response(h, &ack);
	return 1;
}

/* Step down as leader (h->mu held): one waiting caller, else the helper
 * thread when an asynchronous answer is due, takes the lead. */
void client_lead_release(cogw *h)
{
	h->leader = false;
	for (waiter *w = h->waiters; w; w = w->next) {
		if (!w->done) {
			pthread_cond_broadcast(&h->cond);
			return;
		}
	}
	if (h->asyncs)
		pthread_cond_signal(&h->reader_cond);
}
