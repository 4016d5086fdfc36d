/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_send.c - the bottom of libcogw's transport: a line's
 * command queue (opened by name, and noticed when the daemon restarted and
 * replaced it), sending a command there (in chunks when it does not fit
 * one message: docs/mailbox.md "Chunking"), the REGISTER request and a
 * line's registration as the daemon answered it.
 */
#include "mailbox/client_transport.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <mqueue.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Wait until q is ready for events (POLLIN / POLLOUT) or ms pass.
 * Returns > 0 ready, 0 timeout or signal (the caller retries), < 0 error
 * with errno set. */
static int mq_wait(mqd_t q, short events, unsigned ms)
{
	struct pollfd pf = { .fd = (int)q, .events = events };
	int rc = poll(&pf, 1, ms > INT_MAX ? INT_MAX : (int)ms);

	if (rc < 0)
		return errno == EINTR ? 0 : -1;
	if (rc > 0 && (pf.revents & POLLNVAL)) {
		errno = EBADF;
		return -1;
	}
	return rc;
}

/*
 * Is the line's command queue still the one we send to? A daemon that
 * restarts unlinks the old queue and creates a new one: whatever we send
 * to the old descriptor is never read, and the new daemon does not know
 * our registration. There is no notification for that on a message
 * queue, so waits check the name's inode every RESTART_CHECK_MS (and the
 * reader thread every period). On a change the line is marked stale and
 * unregistered, its restart count goes up (waits that began before fail
 * with COGW_E_RESTARTED) and the next use registers again.
 * Returns 0 (unchanged, or not open), COGW_E_RESTARTED.
 */
int client_cmd_queue_check(cogw *h, unsigned line)
{
	line_state *ls = &h->lines[line];
	char qname[MBX_QNAME_MAX];
	struct stat st;
	bool changed;
	mqd_t q;

	pthread_mutex_lock(&h->setup_mu);
	if (ls->cmd == (mqd_t)-1 || ls->stale) {
		changed = ls->stale;
		pthread_mutex_unlock(&h->setup_mu);
		return changed ? COGW_E_RESTARTED : 0;
	}
	pthread_mutex_unlock(&h->setup_mu);
	if (mbx_queue_name(qname, sizeof qname, h->instance, line) < 0)
		return 0;
	q = mq_open(qname, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
	if (q == (mqd_t)-1) {
		changed = errno == ENOENT;
		st.st_ino = 0;
	} else {
		changed = fstat((int)q, &st) == 0 && st.st_ino != ls->cmd_ino;
		mq_close(q);
	}
	pthread_mutex_lock(&h->setup_mu);
	ls->checked_us = mono_us();
	if (changed && !ls->stale && st.st_ino != ls->cmd_ino) {
		ls->stale = true;
		ls->registered = false;
		ls->client = 0;
		ls->token = 0;
		ls->rereg_corr = 0;
		ls->restarts++;
	}
	changed = ls->stale;
	pthread_mutex_unlock(&h->setup_mu);
	return changed ? COGW_E_RESTARTED : 0;
}

unsigned client_restarts_of(cogw *h, unsigned line)
{
	unsigned n;

	pthread_mutex_lock(&h->setup_mu);
	n = h->lines[line].restarts;
	pthread_mutex_unlock(&h->setup_mu);
	return n;
}

/* (Re-)open the line's command queue by name. After a restart the new
 * queue is dup2()ed onto the old descriptor: other threads may hold its
 * number in a snapshot (client_send_cmd), and must never reach an unrelated
 * file that reused it. Call with setup_mu held. */
int client_line_open_cmd(cogw *h, unsigned line)
{
	line_state *ls = &h->lines[line];
	char qname[MBX_QNAME_MAX];
	struct stat st;
	mqd_t q;

	if (mbx_queue_name(qname, sizeof qname, h->instance, line) < 0)
		return COGW_E_INVAL;
	/* non-blocking: send_raw waits with poll() */
	q = mq_open(qname, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
	if (q == (mqd_t)-1)
		return errno == ENOENT   ? COGW_E_NO_DAEMON
		       : errno == EACCES ? COGW_E_ACCESS
					 : COGW_E_SYSTEM;
	if (fstat((int)q, &st) < 0) {
		mq_close(q);
		return COGW_E_SYSTEM;
	}
	if (ls->cmd == (mqd_t)-1) {
		ls->cmd = q;
	} else {
		if (dup3((int)q, (int)ls->cmd, O_CLOEXEC) < 0) {
			mq_close(q);
			return COGW_E_SYSTEM;
		}
		mq_close(q);
	}
	ls->cmd_ino = st.st_ino;
	ls->stale = false;
	return 0;
}

/* q is O_NONBLOCK: a full command queue is waited out with poll(), up to
 * the caller's monotonic deadline. */
static int send_raw(cogw *h, unsigned line, mqd_t q, const uint8_t *msg, size_t n,
		    uint64_t deadline_us)
{
	while (mq_send(q, (const char *)msg, n, 0) < 0) {
		unsigned left;

		if (errno == EINTR)
			continue;
		if (errno != EAGAIN)
			return COGW_E_SYSTEM;
		left = ms_left(deadline_us);
		if (left == 0)
			return COGW_E_TIMEOUT;
		/* a full queue nobody reads any more: the daemon is gone */
		if (client_cmd_queue_check(h, line))
			return COGW_E_RESTARTED;
		if (mq_wait(q, POLLOUT, left < RESTART_CHECK_MS ? left : RESTART_CHECK_MS) < 0)
			return COGW_E_SYSTEM;
	}
	return 0;
}

/* What a command carries: its fixed part, then its data. */
struct cmd_parts {
	const void *fixed;
	size_t flen;
	const uint8_t *data;
	size_t dlen;
};

/* A command that fits one message: fixed then data, both in msg. */
static int send_whole(cogw *h, unsigned line, mqd_t q, mbx_hdr *hd, uint8_t *msg,
		      const struct cmd_parts *cp, uint64_t deadline_us)
{
	if (cp->flen)
		memcpy(msg + MBX_HDR_SIZE, cp->fixed, cp->flen);
	if (cp->dlen)
		memcpy(msg + MBX_HDR_SIZE + cp->flen, cp->data, cp->dlen);
	hd->len = (uint16_t)(cp->flen + cp->dlen);
	mbx_hdr_encode(hd, msg);
	return send_raw(h, line, q, msg, MBX_HDR_SIZE + hd->len, deadline_us);
}

/* A command in chunks of room bytes (docs/mailbox.md "Chunking"): the
 * fixed part and the first data in the first, the rest after it; only
 * data-carrying commands without a size cap, up to the line's limit. */
static int send_chunked(cogw *h, unsigned line, const line_state *ls, mbx_hdr *hd, uint8_t *msg,
			size_t room, const struct cmd_parts *cp, uint64_t deadline_us)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(hd->code);
	uint8_t flags = hd->flags;
	size_t off = 0;
	int rc = 0;

	if (!ci || !(ci->flags & MBX_CI_DATA) || ci->max_data || cp->dlen > ls->max_transfer ||
	    cp->dlen > UINT32_MAX)
		return COGW_E_TOO_BIG;
	for (uint16_t chunk = 0; off < cp->dlen && rc == 0; chunk++) {
		size_t f = chunk == 0 ? cp->flen : 0;
		size_t n = cp->dlen - off;

		if (n > room - f)
			n = room - f;
		hd->flags = flags | MBX_F_CHUNKED | (off + n < cp->dlen ? MBX_F_MORE : 0);
		hd->chunk = chunk;
		hd->total = (uint32_t)cp->dlen;
		hd->len = (uint16_t)(f + n);
		if (f)
			memcpy(msg + MBX_HDR_SIZE, cp->fixed, f);
		memcpy(msg + MBX_HDR_SIZE + f, cp->data + off, n);
		mbx_hdr_encode(hd, msg);
		rc = send_raw(h, line, ls->cmd, msg, MBX_HDR_SIZE + hd->len, deadline_us);
		off += n;
	}
	return rc;
}

int client_send_cmd(cogw *h, unsigned line, uint16_t code, uint8_t flags, uint64_t corr,
		    const void *fixed, size_t flen, const void *data, size_t dlen,
		    uint64_t deadline_us)
{
	const struct cmd_parts cp = { .fixed = fixed, .flen = flen, .data = data, .dlen = dlen };
	line_state ls;
	size_t max_msg;
	uint8_t *msg;
	int rc;

	pthread_mutex_lock(&h->setup_mu);
	ls = h->lines[line];
	pthread_mutex_unlock(&h->setup_mu);
	max_msg = ls.registered ? ls.max_msg : MBX_MSG_MIN;
	if (ls.cmd == (mqd_t)-1)
		return COGW_E_CLOSED;
	if (flen > max_msg - MBX_HDR_SIZE)
		return COGW_E_INVAL;
	mbx_hdr hd = {
		.magic = MBX_MAGIC,
		.version = MBX_VERSION,
		.kind = MBX_KIND_COMMAND,
		.code = code,
		.line = (uint8_t)line,
		.flags = flags,
		.client = ls.client,
		.corr = corr,
		.token = ls.token,
	};
	msg = malloc(max_msg);
	if (!msg)
		return COGW_E_NOMEM;
	if (flen + dlen <= max_msg - MBX_HDR_SIZE)
		rc = send_whole(h, line, ls.cmd, &hd, msg, &cp, deadline_us);
	else
		rc = send_chunked(h, line, &ls, &hd, msg, max_msg - MBX_HDR_SIZE, &cp, deadline_us);
	free(msg);
	if (rc == 0) {
		pthread_mutex_lock(&h->setup_mu);
		h->lines[line].sent_since_ping = true;
		pthread_mutex_unlock(&h->setup_mu);
	}
	return rc;
}

/* The REGISTER request naming this handle's queues. */
void client_register_req(const cogw *h, mbx_register_req *rq)
{
	memset(rq, 0, sizeof *rq);
	rq->pid = (uint32_t)h->pid;
	rq->uid = (uint32_t)geteuid();
	memcpy(rq->resp_queue, h->resp_name, sizeof rq->resp_queue);
	memcpy(rq->event_queue, h->evt_name, sizeof rq->event_queue);
}

/* A line's registration as the daemon answered it (setup_mu held). */
void client_line_registered(line_state *ls, const mbx_register_resp *rs, uint64_t now)
{
	ls->client = rs->client;
	ls->token = rs->token;
	ls->lease_ms = rs->lease_ms;
	ls->max_msg = rs->max_msg < MBX_MSG_MIN ? MBX_MSG_MIN : rs->max_msg;
	if (ls->max_msg > MBX_MSG_MAX)
		ls->max_msg = MBX_MSG_MAX;
	ls->max_transfer = rs->max_transfer;
	ls->registered = true;
	ls->attached = true;
	ls->sent_since_ping = true;
	ls->ping_checked_us = now;
}

uint64_t client_corr_new(cogw *h)
{
	uint64_t c;

	pthread_mutex_lock(&h->mu);
	c = ++h->next_corr;
	pthread_mutex_unlock(&h->mu);
	return c;
}
