/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_async.c - libcogw's asynchronous interface:
 * cogw_send_async() (the helper thread reads its answer), cogw_recv() (the
 * ring of asynchronous answers and the event queue, waited on directly
 * when only events can come), cogw_event_fd() for an event loop.
 */
#include "mailbox/client_transport.h"

#include <errno.h>
#include <limits.h>
#include <mqueue.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int cogw_send_async(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		    uint64_t *corr)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(cmd);
	uint64_t now, deadline, id;
	async_op *a;
	size_t flen;
	int rc;

	if (!h || !ci || (ci->flags & MBX_CI_SERVER) || (len && !payload))
		return COGW_E_INVAL;
	flen = (ci->flags & MBX_CI_DATA) ? ci->fixed : len;
	if (len < flen)
		return COGW_E_INVAL;
	now = mono_us();
	deadline = now + (uint64_t)h->timeout_ms * 1000u;
	rc = client_line_ready(h, line, now, deadline);
	if (rc == 0) /* the helper reads answers nobody waits for */
		rc = client_helper_ensure(h);
	if (rc)
		return rc;
	id = client_corr_new(h);
	a = client_async_add(h, line, cmd, id, 0);
	if (!a)
		return COGW_E_NOMEM;
	/* a is the reader's from here on: its answer may free it */
	if (corr)
		*corr = id;
	rc = client_send_cmd(h, line, cmd, 0, id, payload, flen, (const uint8_t *)payload + flen,
			     len - flen, deadline);
	if (rc)
		client_async_drop(h, a);
	return rc;
}

int cogw_event_fd(cogw *h)
{
	int rc;

	if (!h)
		return COGW_E_INVAL;
	pthread_mutex_lock(&h->mu);
	rc = client_event_fds_open(h);
	if (rc == 0)
		rc = h->epfd;
	pthread_mutex_unlock(&h->mu);
	return rc;
}

void cogw_msg_release(cogw_msg *m)
{
	if (!m)
		return;
	free(m->data);
	m->data = NULL;
	m->len = 0;
}

/* A receive from the event queue: waiting until slice when only events
 * can come (*direct), else a look without waiting. */
static int event_take(cogw *h, cogw_msg *m, uint8_t *buf, uint64_t now, uint64_t slice,
		      bool *direct)
{
	int got;

	pthread_mutex_lock(&h->mu);
	*direct = !h->asyncs && !h->ring_count && !h->closing;
	if (*direct) {
		h->evt_waiters++;
		h->evt_wait_until_us = slice;
	}
	pthread_mutex_unlock(&h->mu);
	got = client_event_pop(h, m, buf, now, *direct ? slice : 0);
	if (*direct) {
		pthread_mutex_lock(&h->mu);
		h->evt_waiters--;
		pthread_mutex_unlock(&h->mu);
	}
	return got;
}

/* Wait for an event or an asynchronous answer until deadline. When no
 * asynchronous answer is due, only the event queue can deliver: wait in
 * mq_timedreceive on it (one system call per event, in monotonic slices
 * like the leader's); otherwise poll() both through the epoll descriptor.
 * now: the monotonic clock as the caller read it, the one monotonic read
 * of a call whose event is waiting or comes within the first slice. */
static int recv_wait(cogw *h, cogw_msg *m, uint8_t *buf, uint64_t now, uint64_t deadline)
{
	for (;;) {
		uint64_t slice = now + RESTART_CHECK_MS * 1000u;
		bool direct;

		if (client_ring_pop(h, m))
			return 0;
		int got = event_take(h, m, buf, now, slice < deadline ? slice : deadline, &direct);

		if (got != 0)
			return got > 0 ? 0 : got;
		now = mono_us();
		if (now >= deadline)
			return COGW_E_AGAIN;
		if (direct)
			continue;
		struct pollfd pf = { .fd = h->epfd, .events = POLLIN };
		uint64_t wait_ms = (deadline - now + 999) / 1000;

		if (poll(&pf, 1, wait_ms > INT_MAX ? INT_MAX : (int)wait_ms) < 0 && errno != EINTR)
			return COGW_E_SYSTEM;
		now = mono_us();
	}
}

int cogw_recv(cogw *h, cogw_msg *m, int timeout_ms)
{
	uint8_t *buf;
	uint64_t now;
	int rc;

	if (!h || !m)
		return COGW_E_INVAL;
	memset(m, 0, sizeof *m);
	if (h->loop) /* no helper thread: the caller is the loop */
		return client_loop_wait(h, m, timeout_ms);
	/* a receiver is long-lived: the helper cuts its waits when the wall
	 * clock steps and keeps it registered across daemon restarts */
	rc = client_helper_ensure(h);
	if (rc)
		return rc;
	buf = malloc(h->evt_msg);
	if (!buf)
		return COGW_E_NOMEM;
	now = mono_us();
	rc = recv_wait(h, m, buf, now,
		       timeout_ms < 0 ? UINT64_MAX : now + (uint64_t)timeout_ms * 1000u);
	free(buf);
	return rc;
}
