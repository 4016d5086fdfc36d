/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_call.c - libcogw's blocking call (client_call(), which
 * every service of client_api_*.c uses): the registration with a line on
 * first use, sending the request and waiting for its answer as leader or
 * follower (leader/follower: see client.c), looking for daemon restarts
 * between slices; and the subscriptions to renew after a restart.
 */
#include "mailbox/client_transport.h"

#include <errno.h>
#include <mqueue.h>
#include <pthread.h>
#include <string.h>

static void waiter_unlink(cogw *h, waiter *w)
{
	for (waiter **pp = &h->waiters; *pp; pp = &(*pp)->next) {
		if (*pp == w) {
			*pp = w->next;
			return;
		}
	}
}

/* One turn as the leader (h->mu held, released around the receive).
 * Returns < 0 when the response queue is unusable. */
static int lead_turn(cogw *h, const waiter *w, uint64_t now, uint64_t until)
{
	int r;

	h->leader = true;
	h->lead_until_us = until;
	pthread_mutex_unlock(&h->mu);
	r = client_lead_read(h, now, until);
	pthread_mutex_lock(&h->mu);
	if (r < 0 || w->done || h->closing)
		client_lead_release(h);
	else
		h->leader = false; /* taken again at once: nobody to wake */
	return r;
}

/* Did the daemon restart under us (then no answer can ever come)? h->mu
 * held, released around the check. */
static bool restarted_meanwhile(cogw *h, unsigned line, unsigned restarts)
{
	bool restarted;

	pthread_mutex_unlock(&h->mu);
	client_cmd_queue_check(h, line);
	restarted = client_restarts_of(h, line) != restarts;
	pthread_mutex_lock(&h->mu);
	return restarted;
}

/* Wait (h->mu held) for w to be done, as the leader reading the response
 * queue when no other thread is, else as a follower woken by the leader;
 * between slices of RESTART_CHECK_MS, look for a daemon restart. now: the
 * caller's clock reading; the clock is read again only when a turn ends
 * without the answer. */
static int wait_answer(cogw *h, waiter *w, unsigned line, unsigned restarts, uint64_t now,
		       uint64_t deadline_us)
{
	uint64_t check_at = now + RESTART_CHECK_MS * 1000u;

	while (!w->done && !h->closing) {
		uint64_t until = check_at < deadline_us ? check_at : deadline_us;

		if (now >= deadline_us)
			return COGW_E_TIMEOUT;
		if (now >= check_at) {
			if (restarted_meanwhile(h, line, restarts) && !w->done)
				return COGW_E_RESTARTED;
			check_at = now + RESTART_CHECK_MS * 1000u;
		} else if (!h->leader) {
			int r = lead_turn(h, w, now, until);

			if (r < 0 && !w->done)
				return COGW_E_SYSTEM;
			/* A wait that outlasts a slice gets the helper thread, which
			 * cuts the next slices short if a step of the wall clock
			 * stretches them (their deadline is CLOCK_REALTIME). A call
			 * answered within its first slice never needs it. */
			if (r == 0 && !w->done && !h->reader_started)
				client_helper_start(h);
		} else {
			struct timespec ts = mono_deadline(until);

			pthread_cond_timedwait(&h->cond, &h->mu, &ts);
		}
		if (!w->done)
			now = mono_us();
	}
	return w->done ? 0 : COGW_E_CLOSED;
}

/* Send and wait for the answer with the same correlation id. */
static int exchange(cogw *h, unsigned line, uint16_t code, const void *fixed, size_t flen,
		    const void *data, size_t dlen, void *rbuf, size_t rcap, size_t *rlen,
		    uint32_t *abort, uint64_t now, uint64_t deadline_us)
{
	waiter w = { .buf = rbuf, .cap = rcap, .code = code, .line = (uint8_t)line };
	unsigned restarts = client_restarts_of(h, line);
	int rc;

	pthread_mutex_lock(&h->mu);
	if (h->closing) {
		pthread_mutex_unlock(&h->mu);
		return COGW_E_CLOSED;
	}
	w.corr = ++h->next_corr;
	w.next = h->waiters;
	h->waiters = &w;
	pthread_mutex_unlock(&h->mu);

	rc = client_send_cmd(h, line, code, 0, w.corr, fixed, flen, data, dlen, deadline_us);

	pthread_mutex_lock(&h->mu);
	if (rc == 0)
		rc = wait_answer(h, &w, line, restarts, now, deadline_us);
	waiter_unlink(h, &w);
	pthread_mutex_unlock(&h->mu);
	if (rc)
		return rc;
	if (rlen)
		*rlen = w.len;
	if (abort)
		*abort = w.abort;
	if (w.status)
		return w.status;
	return w.len > rcap ? COGW_E_TRUNCATED : 0;
}

/* Wait while another thread registers the line (setup_mu held): 0, and
 * the line is registered or this thread's to register, or
 * COGW_E_TIMEOUT. */
static int wait_registering(cogw *h, line_state *ls, uint64_t deadline_us)
{
	while (ls->registering && !ls->registered) {
		struct timespec ts = mono_deadline(deadline_us);

		if (pthread_cond_timedwait(&h->setup_cond, &h->setup_mu, &ts) == ETIMEDOUT)
			return COGW_E_TIMEOUT;
	}
	return 0;
}

/* Claim the line's registration (setup_mu held): its command queue
 * opened (again after a restart). 0 or a cogw_err. */
static int claim_registration(cogw *h, unsigned line)
{
	line_state *ls = &h->lines[line];

	if (ls->cmd == (mqd_t)-1 || ls->stale) {
		int rc = client_line_open_cmd(h, line);

		if (rc)
			return rc;
	}
	ls->registering = true;
	ls->client = 0;
	ls->token = 0;
	return 0;
}

/* The REGISTER exchange of a claimed line, its answer kept; then the
 * line is no longer registering. *sub: what to subscribe to again. */
static int register_line(cogw *h, unsigned line, uint64_t now, uint64_t deadline_us,
			 mbx_subscribe_req *sub, bool *lease)
{
	line_state *ls = &h->lines[line];
	mbx_register_req rq;
	mbx_register_resp rs;
	size_t len = 0;
	int rc;

	client_register_req(h, &rq);
	rc = exchange(h, line, MBX_CMD_REGISTER, &rq, sizeof rq, NULL, 0, &rs, sizeof rs, &len,
		      NULL, now, deadline_us);
	if (rc == 0 && len != sizeof rs)
		rc = COGW_E_PROTOCOL;
	pthread_mutex_lock(&h->setup_mu);
	if (rc == 0)
		client_line_registered(ls, &rs, now);
	*lease = rc == 0 && ls->lease_ms != 0;
	*sub = (mbx_subscribe_req){ .classes = ls->sub_classes, .n_filters = ls->n_filters };
	memcpy(sub->filters, ls->filters, sizeof sub->filters);
	ls->registering = false;
	pthread_cond_broadcast(&h->setup_cond);
	pthread_mutex_unlock(&h->setup_mu);
	return rc;
}

int client_line_ready(cogw *h, unsigned line, uint64_t now, uint64_t deadline_us)
{
	mbx_subscribe_req sub;
	line_state *ls;
	bool lease;
	int rc;

	if (line >= MBX_LINES_MAX)
		return COGW_E_INVAL;
	ls = &h->lines[line];
	pthread_mutex_lock(&h->setup_mu);
	rc = wait_registering(h, ls, deadline_us);
	if (rc == 0 && ls->registered) {
		lease = ls->lease_ms != 0;
		pthread_mutex_unlock(&h->setup_mu);
		return lease ? client_helper_ensure(h) : 0; /* the helper renews it */
	}
	if (rc == 0)
		rc = claim_registration(h, line);
	pthread_mutex_unlock(&h->setup_mu);
	if (rc)
		return rc;
	rc = register_line(h, line, now, deadline_us, &sub, &lease);
	if (lease) /* the helper thread renews it */
		rc = client_helper_ensure(h);
	/* registered again after a restart: subscribe to what we had */
	if (rc == 0 && sub.classes) {
		mbx_subscribe_resp sr;

		exchange(h, line, MBX_CMD_SUBSCRIBE, &sub, sizeof sub, NULL, 0, &sr, sizeof sr,
			 NULL, NULL, mono_us(), deadline_us);
	}
	return rc;
}

/* The common shape of every blocking call (mailbox/client_internal.h). */
int client_call(cogw *h, unsigned line, uint16_t code, const void *fixed, size_t flen,
		const void *data, size_t dlen, void *rbuf, size_t rcap, size_t *rlen,
		uint32_t *abort, unsigned timeout_ms)
{
	uint64_t now, deadline;
	int rc;

	if (!h)
		return COGW_E_INVAL;
	if (abort)
		*abort = 0;
	if (rlen)
		*rlen = 0;
	now = mono_us(); /* the one clock read of a call that is answered at once */
	deadline = now + (uint64_t)(timeout_ms ? timeout_ms : h->timeout_ms) * 1000u;
	rc = client_line_ready(h, line, now, deadline);
	if (rc)
		return rc;
	rc = exchange(h, line, code, fixed, flen, data, dlen, rbuf, rcap, rlen, abort, now,
		      deadline);
	if (rc == COGW_E_NOT_REGISTERED) {
		/* the daemon restarted or reaped us: register again, once */
		pthread_mutex_lock(&h->setup_mu);
		h->lines[line].registered = false;
		pthread_mutex_unlock(&h->setup_mu);
		rc = client_line_ready(h, line, mono_us(), deadline);
		if (rc == 0)
			rc = exchange(h, line, code, fixed, flen, data, dlen, rbuf, rcap, rlen,
				      abort, mono_us(), deadline);
	}
	return rc;
}

int client_subscribed(cogw *h, unsigned line, uint32_t classes, uint8_t n_filters,
		      const mbx_raw_filter filters[MBX_RAW_FILTERS_MAX])
{
	line_state *ls = &h->lines[line];

	pthread_mutex_lock(&h->setup_mu);
	ls->sub_classes |= classes & MBX_EVC_ALL;
	if (classes & MBX_EVC_RAW) {
		ls->n_filters = n_filters;
		memcpy(ls->filters, filters, sizeof ls->filters);
	}
	pthread_mutex_unlock(&h->setup_mu);
	/* an event-only client makes no calls: the helper watches for daemon
	 * restarts and registers and subscribes again by itself */
	return client_helper_ensure(h);
}

void client_unsubscribed(cogw *h, unsigned line, uint32_t classes)
{
	line_state *ls = &h->lines[line];

	pthread_mutex_lock(&h->setup_mu);
	ls->sub_classes &= ~classes;
	if (classes & MBX_EVC_RAW)
		ls->n_filters = 0;
	pthread_mutex_unlock(&h->setup_mu);
}
