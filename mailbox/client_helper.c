/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_helper.c - libcogw's helper thread, started only when
 * something needs it: it leads when asynchronous answers or its own
 * re-registration are due and no caller leads, renews the leases (PING),
 * watches for daemon restarts (failing the asynchronous requests of that
 * line, registering and subscribing again), and wakes waits a step of the
 * wall clock stretched.
 */
#include "mailbox/client_transport.h"

#include <fcntl.h>
#include <mqueue.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <unistd.h>

/* Each time the helper wakes (every lease/6) it looks at each registered
 * line: one that sent nothing since the last look gets a PING, so the
 * daemon hears from us about every lease/3 (two looks), well within the
 * lease even when a wake-up comes late. */
static void send_pings(cogw *h)
{
	uint64_t now = mono_us();

	for (unsigned i = 0; i < MBX_LINES_MAX; i++) {
		line_state *ls = &h->lines[i];
		bool due;

		pthread_mutex_lock(&h->setup_mu);
		due = ls->registered && ls->lease_ms &&
		      now - ls->ping_checked_us >= (uint64_t)ls->lease_ms * 1000u / 12;
		if (due) {
			due = !ls->sent_since_ping;
			ls->sent_since_ping = false;
			ls->ping_checked_us = now;
		}
		pthread_mutex_unlock(&h->setup_mu);
		if (!due)
			continue;
		/* NO_REPLY: a lease renewal needs no answer. A loop handle's
		 * loop never waits for room: the next look sends it again. */
		client_send_cmd(h, i, MBX_CMD_PING, MBX_F_NO_REPLY, 0, NULL, 0, NULL, 0,
				h->loop ? now : now + 100000u);
	}
}

/* Restarts seen by the reader thread: requests sent with cogw_send_async
 * to that line get COGW_E_RESTARTED now (their answers will never come),
 * and a line with subscriptions registers again by itself, so that an
 * event-only client (a logger) carries on without making a call. */
static void fail_asyncs_of_line(cogw *h, unsigned line)
{
	pthread_mutex_lock(&h->mu);
	for (async_op **pp = &h->asyncs; *pp;) {
		async_op *a = *pp;

		if (a->line != line) {
			pp = &a->next;
			continue;
		}
		*pp = a->next;
		free(a->data);
		cogw_msg m = { .kind = MBX_KIND_RESPONSE,
			       .line = a->line,
			       .code = a->code,
			       .status = COGW_E_RESTARTED,
			       .corr = a->corr };
		free(a);
		client_ring_push(h, &m);
	}
	pthread_mutex_unlock(&h->mu);
}

static void reregister_async(cogw *h, unsigned line, uint64_t now)
{
	line_state *ls = &h->lines[line];
	mbx_register_req rq;
	uint64_t corr;

	pthread_mutex_lock(&h->setup_mu);
	if (!ls->stale && ls->registered) {
		pthread_mutex_unlock(&h->setup_mu);
		return;
	}
	if (ls->rereg_corr && now - ls->rereg_sent_us < 2000000u) {
		pthread_mutex_unlock(&h->setup_mu);
		return; /* answer still due */
	}
	if ((ls->registering && !ls->rereg_corr) || (!ls->sub_classes && !h->loop) ||
	    client_line_open_cmd(h, line) != 0) {
		pthread_mutex_unlock(&h->setup_mu);
		return; /* a caller registers / nothing to do / no daemon */
	}
	corr = client_corr_new(h) | REREG_CORR_BIT;
	ls->registering = true;
	ls->rereg_corr = corr;
	ls->rereg_sent_us = now;
	ls->client = 0;
	ls->token = 0;
	pthread_mutex_unlock(&h->setup_mu);
	client_register_req(h, &rq);
	client_send_cmd(h, line, MBX_CMD_REGISTER, 0, corr, &rq, sizeof rq, NULL, 0, now + 100000u);
}

static void check_restarts(cogw *h)
{
	uint64_t now = mono_us();

	for (unsigned i = 0; i < MBX_LINES_MAX; i++) {
		line_state *ls = &h->lines[i];
		bool open, due, stale, rereg, failed;

		pthread_mutex_lock(&h->setup_mu);
		open = ls->cmd != (mqd_t)-1;
		due = open && !ls->stale && now - ls->checked_us >= RESTART_CHECK_MS * 5 * 1000u;
		pthread_mutex_unlock(&h->setup_mu);
		if (!open)
			continue;
		if (due)
			client_cmd_queue_check(h, i);
		pthread_mutex_lock(&h->setup_mu);
		stale = ls->stale;
		rereg = ls->rereg_corr != 0;
		failed = ls->restarts_failed != ls->restarts;
		ls->restarts_failed = ls->restarts;
		pthread_mutex_unlock(&h->setup_mu);
		if (failed) /* by this check or a caller's */
			fail_asyncs_of_line(h, i);
		if (stale || rereg)
			reregister_async(h, i, now);
	}
}

unsigned client_upkeep_period_ms(cogw *h)
{
	unsigned p = 1000;

	pthread_mutex_lock(&h->setup_mu);
	for (unsigned i = 0; i < MBX_LINES_MAX; i++) {
		unsigned l = h->lines[i].lease_ms / 6;

		if (h->lines[i].registered && h->lines[i].lease_ms && l < p)
			p = l ? l : 1;
	}
	pthread_mutex_unlock(&h->setup_mu);
	return p;
}

static bool rereg_pending(cogw *h)
{
	bool any = false;

	pthread_mutex_lock(&h->setup_mu);
	for (unsigned i = 0; i < MBX_LINES_MAX && !any; i++)
		any = h->lines[i].rereg_corr != 0;
	pthread_mutex_unlock(&h->setup_mu);
	return any;
}

void client_upkeep(cogw *h)
{
	send_pings(h);
	check_restarts(h);
}

/* A leader that overran its slice by this much was stretched by a step of
 * the wall clock (its deadline is CLOCK_REALTIME): the helper wakes it. */
#define LEAD_OVERRUN_US 100000u

/* The helper thread (h->mu held): lead when nobody does and something only
 * it waits for is due; otherwise sleep until woken, the period passed, or
 * the leader's slice should have ended. Returns true when it took the lead. */
static bool helper_lead_or_sleep(cogw *h, bool rereg, unsigned period_ms)
{
	uint64_t now = mono_us(), until = now + (uint64_t)period_ms * 1000u;
	struct timespec ts;

	if (!h->leader && (rereg || h->asyncs)) {
		h->leader = true;
		h->lead_until_us = until;
		return true;
	}
	if (h->leader) {
		uint64_t overdue = h->lead_until_us + LEAD_OVERRUN_US;

		if (now >= overdue)
			mq_send(h->self, "", 0, 0); /* a full queue wakes it anyway */
		else if (overdue < until)
			until = overdue;
	}
	if (h->evt_waiters) {
		uint64_t overdue = h->evt_wait_until_us + LEAD_OVERRUN_US;

		if (now >= overdue)
			mq_send(h->evt_self, "", 0, 0);
		else if (overdue < until)
			until = overdue;
	}
	ts = mono_deadline(until);
	pthread_cond_timedwait(&h->reader_cond, &h->mu, &ts);
	return false;
}

static void *reader_main(void *arg)
{
	cogw *h = arg;

	for (;;) {
		bool rereg = rereg_pending(h);
		unsigned period = client_upkeep_period_ms(h);
		bool lead;

		pthread_mutex_lock(&h->mu);
		lead = !h->closing && helper_lead_or_sleep(h, rereg, period);
		bool closing = h->closing;
		pthread_mutex_unlock(&h->mu);
		if (closing)
			break;
		if (lead) {
			uint64_t now = mono_us();
			int r = client_lead_read(h, now, now + (uint64_t)period * 1000u);

			pthread_mutex_lock(&h->mu);
			client_lead_release(h);
			pthread_mutex_unlock(&h->mu);
			if (r < 0)
				break; /* queue gone: nothing more to read */
		}
		client_upkeep(h);
	}
	return NULL;
}

/* The eventfd (asynchronous answers ready) and the epoll descriptor that
 * cogw_event_fd() hands out, opened on first need (h->mu held). */
int client_event_fds_open(cogw *h)
{
	struct epoll_event ev = { .events = EPOLLIN };

	if (h->epfd >= 0)
		return 0;
	h->efd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	h->epfd = epoll_create1(EPOLL_CLOEXEC);
	if (h->efd >= 0 && h->epfd >= 0 && epoll_ctl(h->epfd, EPOLL_CTL_ADD, h->efd, &ev) == 0 &&
	    epoll_ctl(h->epfd, EPOLL_CTL_ADD, (int)h->evt, &ev) == 0)
		return 0;
	if (h->epfd >= 0)
		close(h->epfd);
	if (h->efd >= 0)
		close(h->efd);
	h->efd = h->epfd = -1;
	return COGW_E_SYSTEM;
}

/* Start the helper thread (h->mu held) when the first thing that needs it
 * comes: an asynchronous request, a subscription, a lease to renew,
 * cogw_recv(), a wait longer than one slice (wait_answer). A handle whose
 * blocking calls are answered at once never starts it: its waits look for
 * daemon restarts themselves. Neither does a loop handle. */
int client_helper_start(cogw *h)
{
	/* a loop handle's loop does the helper's work (client_loop.c) */
	if (h->reader_started || h->loop)
		return 0;
	if (h->closing)
		return COGW_E_CLOSED;
	if (client_event_fds_open(h) != 0)
		return COGW_E_SYSTEM;
	if (h->self == (mqd_t)-1)
		h->self = mq_open(h->resp_name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
	if (h->evt_self == (mqd_t)-1)
		h->evt_self = mq_open(h->evt_name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
	if (h->self == (mqd_t)-1 || h->evt_self == (mqd_t)-1 ||
	    pthread_create(&h->reader, NULL, reader_main, h) != 0)
		return COGW_E_SYSTEM;
	h->reader_started = true;
	return 0;
}

int client_helper_ensure(cogw *h)
{
	int rc;

	pthread_mutex_lock(&h->mu);
	rc = client_helper_start(h);
	pthread_mutex_unlock(&h->mu);
	return rc;
}
