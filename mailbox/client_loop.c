/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_loop.c - libcogw for event loops (cogw_loop_*, in
 * mailbox/cogw.h; docs/mailbox.md "Event loops"): a handle without a
 * helper thread whose one descriptor the application's loop waits on.
 *
 * The descriptor is the handle's epoll descriptor watching the response
 * queue, the event queue (POSIX message queue descriptors are pollable on
 * Linux) and the eventfd of the ring of finished answers. The loop itself
 * does what the helper thread would: it reads the response queue
 * (client_lead_read with a deadline already passed, so it never waits),
 * which reassembles chunked answers, sends their XFER_ACKs and queues
 * finished answers in the ring by correlation id (client_recv.c); and it
 * runs the helper's upkeep (leases, restart watch, re-registration) when
 * cogw_loop_timeout_ms() says, answering overdue requests with
 * COGW_E_TIMEOUT: a daemon killed without a successor leaves no other
 * trace (its command queue stays, unread).
 * Sends use the command queue's O_NONBLOCK descriptor with a deadline of
 * now: a full queue is COGW_E_WOULDBLOCK, not a wait.
 * One thread drives a loop handle; the locks taken on the way are the
 * transport's own (h->mu, h->setup_mu), never held across a wait.
 */
#include "mailbox/client_transport.h"

#include <errno.h>
#include <limits.h>
#include <mqueue.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>

int client_loop_setup(cogw *h)
{
	struct epoll_event ev = { .events = EPOLLIN };
	int rc;

	h->loop = true;
	h->loop_buf = malloc(h->evt_msg);
	if (!h->loop_buf)
		return COGW_E_NOMEM;
	pthread_mutex_lock(&h->mu);
	rc = client_event_fds_open(h);
	pthread_mutex_unlock(&h->mu);
	if (rc)
		return rc;
	if (epoll_ctl(h->epfd, EPOLL_CTL_ADD, (int)h->resp, &ev) < 0)
		return COGW_E_SYSTEM;
	h->upkeep_last_us = h->loop_now_us = mono_us();
	return 0;
}

int cogw_loop_fd(cogw *h)
{
	return h && h->loop ? h->epfd : COGW_E_INVAL;
}

int cogw_loop_attach(cogw *h, unsigned line, unsigned timeout_ms)
{
	uint64_t now;

	if (!h || !h->loop)
		return COGW_E_INVAL;
	now = mono_us();
	return client_line_ready(h, line, now,
				 now + (uint64_t)(timeout_ms ? timeout_ms : h->timeout_ms) * 1000u);
}

int cogw_loop_cmd_fd(cogw *h, unsigned line)
{
	int fd;

	if (!h || !h->loop || line >= MBX_LINES_MAX)
		return COGW_E_INVAL;
	pthread_mutex_lock(&h->setup_mu);
	fd = h->lines[line].attached ? (int)h->lines[line].cmd : COGW_E_NOT_REGISTERED;
	pthread_mutex_unlock(&h->setup_mu);
	return fd;
}

/* Can the line take a command now? 0; COGW_E_NOT_REGISTERED (never
 * attached); after a daemon restart COGW_E_WOULDBLOCK while the line
 * registers again (the upkeep is run at once to start that), or
 * COGW_E_NO_DAEMON when there is no command queue to register with. */
static int line_sendable(cogw *h, unsigned line)
{
	line_state *ls = &h->lines[line];
	bool registered, attached, rereg;

	pthread_mutex_lock(&h->setup_mu);
	registered = ls->registered;
	attached = ls->attached;
	pthread_mutex_unlock(&h->setup_mu);
	if (registered)
		return 0;
	if (!attached)
		return COGW_E_NOT_REGISTERED;
	client_upkeep(h);
	pthread_mutex_lock(&h->setup_mu);
	registered = ls->registered;
	rereg = ls->rereg_corr != 0;
	pthread_mutex_unlock(&h->setup_mu);
	return registered ? 0 : rereg ? COGW_E_WOULDBLOCK : COGW_E_NO_DAEMON;
}

/* A command of more than one message (*chunked) is started only when the
 * line's queue has room for all its chunks (for a queue's depth of them
 * when it has more: the daemon takes them in as they come, the rest wait
 * for room up to the request's time-out). */
static bool room_for(cogw *h, unsigned line, size_t flen, size_t dlen, bool *chunked)
{
	struct mq_attr at;
	size_t room;
	mqd_t q;

	pthread_mutex_lock(&h->setup_mu);
	q = h->lines[line].cmd;
	room = h->lines[line].max_msg - MBX_HDR_SIZE;
	pthread_mutex_unlock(&h->setup_mu);
	*chunked = flen + dlen > room;
	if (!*chunked)
		return true;
	if (mq_getattr(q, &at) < 0)
		return true; /* the send reports it */
	long chunks = (long)((flen + dlen + room - 1) / room);

	return at.mq_maxmsg - at.mq_curmsgs >= (chunks < at.mq_maxmsg ? chunks : at.mq_maxmsg);
}

/* As many requests under way as the response queue holds: one more could
 * find it full when its answer comes, and the daemon drops what does not
 * fit (docs/mailbox.md "Event loops"). */
static bool answers_have_room(cogw *h)
{
	unsigned n = 0;

	pthread_mutex_lock(&h->mu);
	for (const async_op *a = h->asyncs; a && n < h->resp_depth; a = a->next)
		n++;
	pthread_mutex_unlock(&h->mu);
	return n < h->resp_depth;
}

int cogw_loop_send(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		   unsigned timeout_ms, uint64_t *corr)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(cmd);
	uint64_t now, id, wait_us;
	bool chunked;
	async_op *a;
	size_t flen;
	int rc;

	if (!h || !h->loop || line >= MBX_LINES_MAX || !ci || (ci->flags & MBX_CI_SERVER) ||
	    (len && !payload))
		return COGW_E_INVAL;
	flen = (ci->flags & MBX_CI_DATA) ? ci->fixed : len;
	if (len < flen)
		return COGW_E_INVAL;
	rc = line_sendable(h, line);
	if (rc)
		return rc;
	if (!answers_have_room(h) || !room_for(h, line, flen, len - flen, &chunked))
		return COGW_E_WOULDBLOCK;
	now = h->loop_now_us = mono_us();
	wait_us = (uint64_t)(timeout_ms ? timeout_ms : h->timeout_ms) * 1000u;
	id = client_corr_new(h);
	a = client_async_add(h, line, cmd, id, now + wait_us);
	if (!a)
		return COGW_E_NOMEM;
	/* one message: a deadline of now (a full queue is no wait); chunks:
	 * room_for() saw room, only a race with other clients waits */
	rc = client_send_cmd(h, line, cmd, 0, id, payload, flen, (const uint8_t *)payload + flen,
			     len - flen, chunked ? now + wait_us : now);
	if (rc) {
		client_async_drop(h, a);
		return rc == COGW_E_TIMEOUT ? COGW_E_WOULDBLOCK : rc;
	}
	if (corr)
		*corr = id;
	return 0;
}

/* One message from the response queue, taken in without waiting (a
 * finished answer goes to the ring): 1 one, 0 none (or a blocking call
 * leads now), < 0 the queue is unusable. */
static int response_take(cogw *h)
{
	int r;

	pthread_mutex_lock(&h->mu);
	if (h->leader) {
		pthread_mutex_unlock(&h->mu);
		return 0;
	}
	h->leader = true;
	h->lead_until_us = 0;
	h->loop_taking = true;
	pthread_mutex_unlock(&h->mu);
	r = client_lead_read(h, 0, 0); /* a deadline passed: no wait */
	pthread_mutex_lock(&h->mu);
	h->loop_taking = false;
	client_lead_release(h);
	pthread_mutex_unlock(&h->mu);
	return r;
}

int cogw_loop_recv(cogw *h, cogw_msg *m)
{
	int r;

	if (!h || !h->loop || !m)
		return COGW_E_INVAL;
	memset(m, 0, sizeof *m);
	for (;;) {
		if (client_ring_pop(h, m))
			return 0;
		r = response_take(h);
		if (r < 0)
			return COGW_E_SYSTEM;
		if (r == 0)
			break;
	}
	r = client_event_pop(h, m, h->loop_buf, 0, 0);
	return r > 0 ? 0 : r < 0 ? r : COGW_E_AGAIN;
}

int cogw_loop_timeout_ms(cogw *h)
{
	uint64_t due, now;

	if (!h || !h->loop)
		return COGW_E_INVAL;
	/* the period follows the leases of the lines registered since */
	due = h->upkeep_last_us + (uint64_t)client_upkeep_period_ms(h) * 1000u;
	pthread_mutex_lock(&h->mu);
	for (const async_op *a = h->asyncs; a; a = a->next)
		if (a->deadline_us && a->deadline_us < due)
			due = a->deadline_us;
	pthread_mutex_unlock(&h->mu);
	now = h->loop_now_us;
	if (due <= now)
		return 0;
	due = (due - now + 999) / 1000;
	return due > INT_MAX ? INT_MAX : (int)due;
}

/* Requests past their deadline get their answer now: COGW_E_TIMEOUT. */
static void expire_requests(cogw *h, uint64_t now)
{
	pthread_mutex_lock(&h->mu);
	for (async_op **pp = &h->asyncs; *pp;) {
		async_op *a = *pp;

		if (!a->deadline_us || a->deadline_us > now) {
			pp = &a->next;
			continue;
		}
		*pp = a->next;
		cogw_msg m = { .kind = MBX_KIND_RESPONSE,
			       .line = a->line,
			       .code = a->code,
			       .status = COGW_E_TIMEOUT,
			       .corr = a->corr };
		free(a->data);
		free(a);
		client_ring_push(h, &m);
	}
	pthread_mutex_unlock(&h->mu);
}

void cogw_loop_tick(cogw *h)
{
	uint64_t now;

	if (!h || !h->loop)
		return;
	now = h->loop_now_us = mono_us();
	if (now - h->upkeep_last_us >= (uint64_t)client_upkeep_period_ms(h) * 1000u) {
		client_upkeep(h);
		h->upkeep_last_us = now;
	}
	expire_requests(h, now);
}

int client_loop_wait(cogw *h, cogw_msg *m, int timeout_ms)
{
	uint64_t now = h->loop_now_us = mono_us();
	uint64_t deadline = timeout_ms < 0 ? UINT64_MAX : now + (uint64_t)timeout_ms * 1000u;

	for (;;) {
		int rc = cogw_loop_recv(h, m);

		if (rc != COGW_E_AGAIN)
			return rc;
		now = h->loop_now_us = mono_us();
		if (now >= deadline)
			return COGW_E_AGAIN;
		uint64_t left_ms = (deadline - now + 999) / 1000;
		int wait_ms = cogw_loop_timeout_ms(h);
		struct pollfd pf = { .fd = h->epfd, .events = POLLIN };

		if ((uint64_t)wait_ms > left_ms)
			wait_ms = (int)left_ms;
		if (poll(&pf, 1, wait_ms) < 0 && errno != EINTR)
			return COGW_E_SYSTEM;
		cogw_loop_tick(h);
	}
}
