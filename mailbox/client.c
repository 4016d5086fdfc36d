/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client.c - libcogw's transport: registration, sending, waiting
 * for answers, the helper thread, chunk reassembly, leases, the handle's
 * life and the asynchronous interface. The services (cogw_od_read, cogw_lss,
 * ...) are in mailbox/client_api_*.c and reach this file only through
 * client_call() and the subscription bookkeeping (mailbox/client_internal.h).
 *
 * Structure: one handle = one response queue + one event queue of this
 * process, a helper thread, and per line the registration (client id +
 * token) and the line's command queue.
 * - The response queue is read by one thread at a time, the leader
 *   (leader/follower): a blocking call puts a waiter (keyed by a
 *   correlation id unique in the handle) on a list, sends, and when no
 *   other thread is reading becomes the leader itself and receives its own
 *   answer directly (no hand-off, no wake-up of another thread). Whatever
 *   the leader receives for someone else fills that waiter's buffer and
 *   wakes it; when the leader's own answer is complete it steps down and
 *   wakes one of the threads still waiting to lead. So answers can come
 *   back in any order, from any line, to any number of threads.
 * - The helper thread leads only when no caller is waiting and something
 *   else is due: asynchronous answers (cogw_send_async), which it
 *   reassembles into heap buffers queued in a bounded ring for cogw_recv()
 *   (an eventfd makes them visible to epoll next to the event queue), and
 *   the answer to its own re-registration after a daemon restart. It also
 *   renews the leases (PING) and watches for restarts.
 * - Chunked answers are flow-controlled: the server keeps at most half of
 *   our response queue filled with chunks of one transfer and waits for
 *   XFER_ACK, which whoever reads them sends every quarter queue.
 * - The leader waits with mq_timedreceive, one system call, in slices of
 *   at most RESTART_CHECK_MS: each slice's CLOCK_REALTIME deadline is
 *   derived from the CLOCK_MONOTONIC time left, so a step of the wall
 *   clock (early boot, NTP) cuts a slice short (the loop goes on by the
 *   monotonic clock) or stretches it; a stretched slice is cut by the
 *   helper thread, which wakes a leader that overran its monotonic slice
 *   end with an empty message. Waits for room in a full command queue are
 *   poll() with a monotonic timeout on a non-blocking descriptor.
 * - cogw_recv() waits the same way on the event queue itself while no
 *   asynchronous answer is due (one system call per event); a
 *   cogw_send_async() meanwhile wakes it with an empty message, and with
 *   answers due it polls the epoll descriptor (event queue + eventfd). The
 *   eventfd is written once when the ring of answers becomes non-empty and
 *   read once when it empties, not on every push and pop.
 * This is not on a real-time path: mutexes, malloc and sends that wait
 * (up to a deadline) for room in a full command queue are fine here.
 */
#include "mailbox/client_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <mqueue.h>
#include <poll.h>
#include <stddef.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

_Static_assert((int)COGW_E_NO_MEMORY == (int)MBX_STATUS_MIN,
	       "cogw_err must cover every mbx_status");

#define ASYNC_RING 64u
#define DEFAULT_TIMEOUT_MS 5000u

typedef struct waiter {
	struct waiter *next;
	uint64_t corr;
	uint16_t code;
	uint8_t line;
	bool done;
	int status;
	uint32_t abort;
	uint8_t *buf;
	size_t cap;
	size_t len; /* bytes received (may exceed cap: truncated) */
	uint16_t next_chunk;
} waiter;

typedef struct async_op {
	struct async_op *next;
	uint64_t corr;
	uint8_t line;
	uint16_t code;
	int status;
	uint32_t abort;
	uint32_t dropped;
	uint8_t *data;
	size_t len, total;
	uint16_t next_chunk;
} async_op;

typedef struct line_state {
	bool registered;
	bool registering; /* a thread is registering: others wait */
	/* The daemon restarted (the command queue behind the name is another
	 * one, or gone): cmd must be re-opened by name and the line
	 * registered again (line_ready). */
	bool stale;
	mqd_t cmd;
	ino_t cmd_ino;            /* the queue cmd refers to */
	unsigned restarts;        /* counts restarts seen: a wait that began
	                    * before one fails with COGW_E_RESTARTED */
	unsigned restarts_failed; /* asyncs failed up to this count */
	uint64_t checked_us;      /* last cmd_queue_check */
	/* what to subscribe again after a restart */
	uint32_t sub_classes;
	uint8_t n_filters;
	mbx_raw_filter filters[MBX_RAW_FILTERS_MAX];
	/* reader thread: a re-registration sent by itself (event-only
	 * clients make no calls that would re-register) */
	uint64_t rereg_corr;
	uint64_t rereg_sent_us;
	uint32_t client;
	uint64_t token;
	uint32_t lease_ms;
	uint32_t max_msg;
	uint32_t max_transfer;
	/* lease renewal: something was sent since the helper last looked
	 * (at ping_checked_us); if not, it sends a PING. No clock read per send. */
	bool sent_since_ping;
	uint64_t ping_checked_us;
} line_state;

struct cogw {
	char instance[MBX_INSTANCE_MAX + 1];
	char resp_name[MBX_QNAME_MAX], evt_name[MBX_QNAME_MAX];
	pid_t pid;
	mqd_t resp, evt;
	size_t resp_msg, evt_msg;
	unsigned resp_depth;
	unsigned timeout_ms;
	pthread_t reader;

	/* Opened with the helper thread (helper_start), which is started only
	 * when something needs it: a one-shot handle (open, one call, close)
	 * runs without it (docs/fastpath.md "One-shot cogwctl"). Set under
	 * mu; -1 / false until then. self: O_WRONLY on resp, to wake the
	 * leader; evt_self: O_WRONLY on evt, to wake a cogw_recv() waiting on
	 * it. efd/epfd (cogw_event_fd) may be opened without the helper. */
	bool reader_started;
	mqd_t self, evt_self;
	int efd, epfd;

	pthread_mutex_t mu;         /* everything below */
	pthread_cond_t cond;        /* waiters: an answer came, or the lead is free */
	pthread_cond_t reader_cond; /* the helper thread: an async is due, closing */
	bool closing;
	/* A thread is reading the response queue, until lead_until_us
	 * (monotonic) at the latest; lead_buf is its receive buffer. */
	bool leader;
	uint64_t lead_until_us;
	uint8_t *lead_buf;
	/* cogw_recv() callers waiting in mq_timedreceive on the event queue
	 * (no asynchronous answer can come meanwhile), the latest one's slice
	 * end; efd_set: the eventfd was written and not read since. */
	unsigned evt_waiters;
	uint64_t evt_wait_until_us;
	bool efd_set;
	uint64_t next_corr;
	waiter *waiters;
	async_op *asyncs;
	cogw_msg ring[ASYNC_RING];
	unsigned ring_head, ring_count;
	cogw_stats stats;

	/* The line table. Held only briefly (never across a wait), so the
	 * reader thread can always take it to send an XFER_ACK or a PING. */
	pthread_mutex_t setup_mu;
	pthread_cond_t setup_cond; /* registration finished */
	line_state lines[MBX_LINES_MAX];
};

/* ---- small helpers ---------------------------------------------------------- */

static uint64_t mono_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static struct timespec mono_deadline(uint64_t at_us)
{
	return (struct timespec){ .tv_sec = (time_t)(at_us / 1000000u),
				  .tv_nsec = (long)(at_us % 1000000u) * 1000L };
}

/* CLOCK_REALTIME deadline for mq_timed*: until_us (monotonic) as seen at
 * now (monotonic, read by the caller: in a VM every clock read can be a
 * system call); {0, 0} = already passed (do not wait). */
static struct timespec realtime_deadline(uint64_t now, uint64_t until_us)
{
	struct timespec at = { 0, 0 };
	uint64_t left;

	if (until_us <= now)
		return at;
	left = until_us - now;
	clock_gettime(CLOCK_REALTIME, &at);
	at.tv_sec += (time_t)(left / 1000000u);
	at.tv_nsec += (long)(left % 1000000u) * 1000L;
	if (at.tv_nsec >= 1000000000L) {
		at.tv_sec++;
		at.tv_nsec -= 1000000000L;
	}
	return at;
}

static unsigned ms_left(uint64_t deadline_us)
{
	uint64_t now = mono_us();

	return now >= deadline_us ? 0 : (unsigned)((deadline_us - now + 999) / 1000);
}

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

static unsigned long read_proc(const char *path, unsigned long dflt)
{
	FILE *f = fopen(path, "re");
	unsigned long v = dflt;

	if (f) {
		if (fscanf(f, "%lu", &v) != 1)
			v = dflt;
		fclose(f);
	}
	return v;
}

const char *cogw_strerror(int err)
{
	if (err <= 0 && err >= MBX_STATUS_MIN)
		return mbx_status_to_string(err);
	switch (err) {
	case COGW_E_NO_DAEMON:
		return "daemon not running (no command queue)";
	case COGW_E_SYSTEM:
		return "system call failed";
	case COGW_E_INVAL:
		return "invalid argument";
	case COGW_E_NOMEM:
		return "out of memory";
	case COGW_E_AGAIN:
		return "nothing received";
	case COGW_E_TRUNCATED:
		return "answer truncated (buffer too small)";
	case COGW_E_CLOSED:
		return "handle closing";
	case COGW_E_PROTOCOL:
		return "unexpected message from the daemon";
	case COGW_E_RESTARTED:
		return "the daemon restarted: request not completed (retry)";
	case COGW_E_QUEUE_LIMIT:
		return "this user's message-queue memory is used up (RLIMIT_MSGQUEUE:"
		       " raise it with ulimit -q or LimitMSGQUEUE=)";
	}
	return "unknown error";
}

/* ---- daemon restarts ------------------------------------------------------------ */

#define RESTART_CHECK_MS 200u

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
static int cmd_queue_check(cogw *h, unsigned line)
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

static unsigned restarts_of(cogw *h, unsigned line)
{
	unsigned n;

	pthread_mutex_lock(&h->setup_mu);
	n = h->lines[line].restarts;
	pthread_mutex_unlock(&h->setup_mu);
	return n;
}

/* (Re-)open the line's command queue by name. After a restart the new
 * queue is dup2()ed onto the old descriptor: other threads may hold its
 * number in a snapshot (send_cmd), and must never reach an unrelated
 * file that reused it. Call with setup_mu held. */
static int line_open_cmd(cogw *h, unsigned line)
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

/* ---- sending ------------------------------------------------------------------ */

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
		if (cmd_queue_check(h, line))
			return COGW_E_RESTARTED;
		if (mq_wait(q, POLLOUT, left < RESTART_CHECK_MS ? left : RESTART_CHECK_MS) < 0)
			return COGW_E_SYSTEM;
	}
	return 0;
}

/* Send a command, chunked when payload + data do not fit one message. */
static int send_cmd(cogw *h, unsigned line, uint16_t code, uint8_t flags, uint64_t corr,
		    const void *fixed, size_t flen, const void *data, size_t dlen,
		    uint64_t deadline_us)
{
	line_state snap, *ls = &snap;
	size_t max_msg;

	pthread_mutex_lock(&h->setup_mu);
	snap = h->lines[line];
	pthread_mutex_unlock(&h->setup_mu);
	max_msg = ls->registered ? ls->max_msg : MBX_MSG_MIN;
	if (ls->cmd == (mqd_t)-1)
		return COGW_E_CLOSED;
	{
	}
	size_t room = max_msg - MBX_HDR_SIZE;
	const uint8_t *d = data;
	uint8_t *msg;
	int rc = 0;
	mbx_hdr hd = {
		.magic = MBX_MAGIC,
		.version = MBX_VERSION,
		.kind = MBX_KIND_COMMAND,
		.code = code,
		.line = (uint8_t)line,
		.flags = flags,
		.client = ls->client,
		.corr = corr,
		.token = ls->token,
	};

	if (flen > room)
		return COGW_E_INVAL;
	msg = malloc(max_msg);
	if (!msg)
		return COGW_E_NOMEM;
	if (flen + dlen <= room) {
		if (flen)
			memcpy(msg + MBX_HDR_SIZE, fixed, flen);
		if (dlen)
			memcpy(msg + MBX_HDR_SIZE + flen, d, dlen);
		hd.len = (uint16_t)(flen + dlen);
		mbx_hdr_encode(&hd, msg);
		rc = send_raw(h, line, ls->cmd, msg, MBX_HDR_SIZE + hd.len, deadline_us);
		goto out;
	}
	const mbx_cmd_info *ci = mbx_cmd_lookup(code);

	if (!ci || !(ci->flags & MBX_CI_DATA) || ci->max_data || dlen > ls->max_transfer ||
	    dlen > UINT32_MAX) {
		rc = COGW_E_TOO_BIG;
		goto out;
	}
	size_t off = 0;

	for (uint16_t chunk = 0; off < dlen; chunk++) {
		size_t f = chunk == 0 ? flen : 0;
		size_t n = dlen - off;

		if (n > room - f)
			n = room - f;
		hd.flags = flags | MBX_F_CHUNKED | (off + n < dlen ? MBX_F_MORE : 0);
		hd.chunk = chunk;
		hd.total = (uint32_t)dlen;
		hd.len = (uint16_t)(f + n);
		if (f)
			memcpy(msg + MBX_HDR_SIZE, fixed, f);
		memcpy(msg + MBX_HDR_SIZE + f, d + off, n);
		mbx_hdr_encode(&hd, msg);
		rc = send_raw(h, line, ls->cmd, msg, MBX_HDR_SIZE + hd.len, deadline_us);
		if (rc)
			break;
		off += n;
	}
out:
	free(msg);
	if (rc == 0) {
		pthread_mutex_lock(&h->setup_mu);
		h->lines[line].sent_since_ping = true;
		pthread_mutex_unlock(&h->setup_mu);
	}
	return rc;
}

/* ---- waiting --------------------------------------------------------------------- */

static void waiter_unlink(cogw *h, waiter *w)
{
	for (waiter **pp = &h->waiters; *pp; pp = &(*pp)->next) {
		if (*pp == w) {
			*pp = w->next;
			return;
		}
	}
}

static uint64_t corr_new(cogw *h)
{
	uint64_t c;

	pthread_mutex_lock(&h->mu);
	c = ++h->next_corr;
	pthread_mutex_unlock(&h->mu);
	return c;
}

static int lead_read(cogw *h, uint64_t now, uint64_t until_us);
static void lead_release(cogw *h);
static int helper_start(cogw *h);
static int helper_ensure(cogw *h);

/* One turn as the leader (h->mu held, released around the receive).
 * Returns < 0 when the response queue is unusable. */
static int lead_turn(cogw *h, const waiter *w, uint64_t now, uint64_t until)
{
	int r;

	h->leader = true;
	h->lead_until_us = until;
	pthread_mutex_unlock(&h->mu);
	r = lead_read(h, now, until);
	pthread_mutex_lock(&h->mu);
	if (r < 0 || w->done || h->closing)
		lead_release(h);
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
	cmd_queue_check(h, line);
	restarted = restarts_of(h, line) != restarts;
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
				helper_start(h);
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
	unsigned restarts = restarts_of(h, line);
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

	rc = send_cmd(h, line, code, 0, w.corr, fixed, flen, data, dlen, deadline_us);

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

/* Register with a line on first use. One thread registers, others that
 * need the same line meanwhile wait for it. now: the caller's clock
 * reading (the registration's wait and lease bookkeeping start there). */
static int line_ready(cogw *h, unsigned line, uint64_t now, uint64_t deadline_us)
{
	line_state *ls;
	mbx_register_req rq;
	mbx_register_resp rs;
	size_t len = 0;
	int rc = 0;

	if (line >= MBX_LINES_MAX)
		return COGW_E_INVAL;
	ls = &h->lines[line];
	pthread_mutex_lock(&h->setup_mu);
	while (ls->registering && !ls->registered) {
		struct timespec ts = mono_deadline(deadline_us);

		if (pthread_cond_timedwait(&h->setup_cond, &h->setup_mu, &ts) == ETIMEDOUT) {
			pthread_mutex_unlock(&h->setup_mu);
			return COGW_E_TIMEOUT;
		}
	}
	if (ls->registered) {
		bool lease = ls->lease_ms != 0;

		pthread_mutex_unlock(&h->setup_mu);
		return lease ? helper_ensure(h) : 0; /* the helper renews it */
	}
	if (ls->cmd == (mqd_t)-1 || ls->stale) {
		rc = line_open_cmd(h, line);
		if (rc) {
			pthread_mutex_unlock(&h->setup_mu);
			return rc;
		}
	}
	ls->registering = true;
	ls->client = 0;
	ls->token = 0;
	pthread_mutex_unlock(&h->setup_mu);

	memset(&rq, 0, sizeof rq);
	rq.pid = (uint32_t)h->pid;
	rq.uid = (uint32_t)geteuid();
	memcpy(rq.resp_queue, h->resp_name, sizeof rq.resp_queue);
	memcpy(rq.event_queue, h->evt_name, sizeof rq.event_queue);
	rc = exchange(h, line, MBX_CMD_REGISTER, &rq, sizeof rq, NULL, 0, &rs, sizeof rs, &len,
		      NULL, now, deadline_us);
	if (rc == 0 && len != sizeof rs)
		rc = COGW_E_PROTOCOL;

	pthread_mutex_lock(&h->setup_mu);
	if (rc == 0) {
		ls->client = rs.client;
		ls->token = rs.token;
		ls->lease_ms = rs.lease_ms;
		ls->max_msg = rs.max_msg < MBX_MSG_MIN ? MBX_MSG_MIN : rs.max_msg;
		if (ls->max_msg > MBX_MSG_MAX)
			ls->max_msg = MBX_MSG_MAX;
		ls->max_transfer = rs.max_transfer;
		ls->registered = true;
		ls->sent_since_ping = true;
		ls->ping_checked_us = now;
	}
	bool lease = rc == 0 && ls->lease_ms != 0;
	mbx_subscribe_req sub = { .classes = ls->sub_classes, .n_filters = ls->n_filters };

	memcpy(sub.filters, ls->filters, sizeof sub.filters);
	ls->registering = false;
	pthread_cond_broadcast(&h->setup_cond);
	pthread_mutex_unlock(&h->setup_mu);
	if (lease) /* the helper thread renews it */
		rc = helper_ensure(h);
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
	rc = line_ready(h, line, now, deadline);
	if (rc)
		return rc;
	rc = exchange(h, line, code, fixed, flen, data, dlen, rbuf, rcap, rlen, abort, now,
		      deadline);
	if (rc == COGW_E_NOT_REGISTERED) {
		/* the daemon restarted or reaped us: register again, once */
		pthread_mutex_lock(&h->setup_mu);
		h->lines[line].registered = false;
		pthread_mutex_unlock(&h->setup_mu);
		rc = line_ready(h, line, mono_us(), deadline);
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
	return helper_ensure(h);
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

/* ---- the reader thread ----------------------------------------------------------- */

static void ring_push(cogw *h, cogw_msg *m)
{
	uint64_t one = 1;

	if (h->ring_count == ASYNC_RING) {
		h->stats.async_dropped++;
		free(m->data);
		return;
	}
	h->ring[(h->ring_head + h->ring_count) % ASYNC_RING] = *m;
	h->ring_count++;
	if (h->efd_set)
		return; /* readable already: one write per non-empty spell */
	h->efd_set = true;
	if (write(h->efd, &one, sizeof one) < 0) {
		/* counter saturated: it is readable anyway */
	}
}

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

/* Correlation ids of the reader thread's own re-registrations: never
 * one of corr_new()'s. */
#define REREG_CORR_BIT (1ull << 63)

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
	ring_push(h, &m);
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
	if ((hd.corr & REREG_CORR_BIT) && hd.code == MBX_CMD_REGISTER) {
		ack->rereg = true;
		ack->line = hd.line;
		ack->corr = hd.corr;
		ack->rereg_status = hd.len == sizeof ack->rereg_resp ? hd.status : COGW_E_PROTOCOL;
		if (hd.len == sizeof ack->rereg_resp)
			memcpy(&ack->rereg_resp, p, sizeof ack->rereg_resp);
		return;
	}
	for (waiter *w = h->waiters; w; w = w->next) {
		if (w->corr == hd.corr && !w->done) {
			if (feed_waiter(h, w, &hd, p, ack)) {
				w->done = true;
				pthread_cond_broadcast(&h->cond);
			}
			return;
		}
	}
	for (async_op **pp = &h->asyncs; *pp; pp = &(*pp)->next) {
		if ((*pp)->corr == hd.corr) {
			feed_async(h, pp, &hd, p, ack);
			return;
		}
	}
	/* A line answers a registration of our queues again, under the corr
	 * of whichever REGISTER named them, at most every 100 ms: ours may
	 * have gone unanswered (docs/mailbox.md "Security model"). */
	for (waiter *w = h->waiters; w && hd.code == MBX_CMD_REGISTER && hd.status == 0;
	     w = w->next) {
		if (w->code == MBX_CMD_REGISTER && w->line == hd.line && !w->done &&
		    feed_waiter(h, w, &hd, p, ack)) {
			w->done = true;
			pthread_cond_broadcast(&h->cond);
			return;
		}
	}
	h->stats.stray_responses++;
}

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
		/* NO_REPLY: a lease renewal needs no answer */
		send_cmd(h, i, MBX_CMD_PING, MBX_F_NO_REPLY, 0, NULL, 0, NULL, 0, now + 100000u);
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
		ring_push(h, &m);
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
	if ((ls->registering && !ls->rereg_corr) || !ls->sub_classes ||
	    line_open_cmd(h, line) != 0) {
		pthread_mutex_unlock(&h->setup_mu);
		return; /* a caller registers / nothing to do / no daemon */
	}
	corr = corr_new(h) | REREG_CORR_BIT;
	ls->registering = true;
	ls->rereg_corr = corr;
	ls->rereg_sent_us = now;
	ls->client = 0;
	ls->token = 0;
	pthread_mutex_unlock(&h->setup_mu);
	memset(&rq, 0, sizeof rq);
	rq.pid = (uint32_t)h->pid;
	rq.uid = (uint32_t)geteuid();
	memcpy(rq.resp_queue, h->resp_name, sizeof rq.resp_queue);
	memcpy(rq.event_queue, h->evt_name, sizeof rq.event_queue);
	send_cmd(h, line, MBX_CMD_REGISTER, 0, corr, &rq, sizeof rq, NULL, 0, now + 100000u);
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
	if (t->rereg_status == 0) {
		const mbx_register_resp *rs = &t->rereg_resp;

		ls->client = rs->client;
		ls->token = rs->token;
		ls->lease_ms = rs->lease_ms;
		ls->max_msg = rs->max_msg < MBX_MSG_MIN ? MBX_MSG_MIN : rs->max_msg;
		if (ls->max_msg > MBX_MSG_MAX)
			ls->max_msg = MBX_MSG_MAX;
		ls->max_transfer = rs->max_transfer;
		ls->registered = true;
		ls->sent_since_ping = true;
		ls->ping_checked_us = mono_us();
	}
	sub = (mbx_subscribe_req){ .classes = ls->sub_classes, .n_filters = ls->n_filters };
	memcpy(sub.filters, ls->filters, sizeof sub.filters);
	pthread_cond_broadcast(&h->setup_cond);
	pthread_mutex_unlock(&h->setup_mu);
	if (t->rereg_status == 0)
		send_cmd(h, t->line, MBX_CMD_SUBSCRIBE, MBX_F_NO_REPLY, 0, &sub, sizeof sub, NULL,
			 0, mono_us() + 100000u);
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
			cmd_queue_check(h, i);
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

static unsigned reader_period_ms(cogw *h)
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

/* After a message: the XFER_ACK it asked for, the re-registration it
 * answered. Called without h->mu. */
static void after_response(cogw *h, const ack_todo *ack)
{
	if (ack->needed) {
		mbx_xfer_ack a = { .next_chunk = ack->next_chunk };

		send_cmd(h, ack->line, MBX_CMD_XFER_ACK, 0, ack->corr, &a, sizeof a, NULL, 0,
			 mono_us() + 1000000u);
	}
	if (ack->rereg)
		reregister_done(h, ack);
}

/* The leader (h->leader set by the caller, h->mu not held): receive one
 * message from the response queue, waiting until until_us (monotonic) at
 * most, and handle it. Returns 1 a message, 0 none (timeout, signal, a
 * wake-up), -1 the queue is unusable. */
static int lead_read(cogw *h, uint64_t now, uint64_t until_us)
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
static void lead_release(cogw *h)
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

static bool rereg_pending(cogw *h)
{
	bool any = false;

	pthread_mutex_lock(&h->setup_mu);
	for (unsigned i = 0; i < MBX_LINES_MAX && !any; i++)
		any = h->lines[i].rereg_corr != 0;
	pthread_mutex_unlock(&h->setup_mu);
	return any;
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
		unsigned period = reader_period_ms(h);
		bool lead;

		pthread_mutex_lock(&h->mu);
		lead = !h->closing && helper_lead_or_sleep(h, rereg, period);
		bool closing = h->closing;
		pthread_mutex_unlock(&h->mu);
		if (closing)
			break;
		if (lead) {
			uint64_t now = mono_us();
			int r = lead_read(h, now, now + (uint64_t)period * 1000u);

			pthread_mutex_lock(&h->mu);
			lead_release(h);
			pthread_mutex_unlock(&h->mu);
			if (r < 0)
				break; /* queue gone: nothing more to read */
		}
		send_pings(h);
		check_restarts(h);
	}
	return NULL;
}

/* ---- open / close ------------------------------------------------------------------ */

/* The eventfd (asynchronous answers ready) and the epoll descriptor that
 * cogw_event_fd() hands out, opened on first need (h->mu held). */
static int event_fds_open(cogw *h)
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
 * daemon restarts themselves. */
static int helper_start(cogw *h)
{
	if (h->reader_started)
		return 0;
	if (h->closing)
		return COGW_E_CLOSED;
	if (event_fds_open(h) != 0)
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

static int helper_ensure(cogw *h)
{
	int rc;

	pthread_mutex_lock(&h->mu);
	rc = helper_start(h);
	pthread_mutex_unlock(&h->mu);
	return rc;
}

static mqd_t make_queue(const char *name, unsigned mode, unsigned depth, unsigned msgsize,
			int oflags)
{
	struct mq_attr attr = { .mq_maxmsg = depth, .mq_msgsize = msgsize };
	mqd_t q = mq_open(name, O_CREAT | O_EXCL | O_CLOEXEC | oflags, mode, &attr);

	/* the umask filters mode: make it exactly what we asked (0600
	 * matters: the daemon refuses queues others could read) */
	if (q != (mqd_t)-1 && fchmod((int)q, mode) < 0) {
		int e = errno;

		mq_close(q);
		mq_unlink(name);
		errno = e;
		return (mqd_t)-1;
	}
	return q;
}

/* mq_open says EMFILE both when the process has no file descriptor left and
 * when the user's RLIMIT_MSGQUEUE bytes are spent; only the second leaves a
 * descriptor free, and it wants a different remedy. */
static int queue_create_error(void)
{
	if (errno != EMFILE)
		return COGW_E_SYSTEM;
	int probe = eventfd(0, EFD_CLOEXEC);

	if (probe >= 0)
		close(probe);
	errno = EMFILE;
	return probe >= 0 ? COGW_E_QUEUE_LIMIT : COGW_E_SYSTEM;
}

int cogw_open(cogw **out, const char *instance)
{
	cogw_options o = { .instance = instance };

	return cogw_open_opts(out, &o);
}

/* Without CAP_SYS_RESOURCE a queue cannot exceed the sysctl limits
 * (containers often lack it even as root): when the kernel refuses a size
 * (EINVAL), clamp to them, so that a default system (msg_max 10) still
 * works; the daemon copes with any depth. Read only then: two files of
 * /proc are eight system calls for every start of a one-shot client. */
static void clamp_to_system(unsigned *depth, unsigned *depth2, unsigned *msgsize)
{
	unsigned long msg_max = read_proc("/proc/sys/fs/mqueue/msg_max", 10);
	unsigned long msgsize_max = read_proc("/proc/sys/fs/mqueue/msgsize_max", 8192);

	if (*depth > msg_max)
		*depth = (unsigned)msg_max;
	if (*depth2 > msg_max)
		*depth2 = (unsigned)msg_max;
	if (*msgsize > msgsize_max)
		*msgsize = (unsigned)msgsize_max;
}

int cogw_open_opts(cogw **out, const cogw_options *o)
{
	cogw *h;
	unsigned mode, rdepth, edepth, msgsize;
	bool clamped = false;
	uint32_t rnd[3] = { 0 };
	int rc = COGW_E_SYSTEM;

	if (!out || !o || !mbx_instance_is_valid(o->instance))
		return COGW_E_INVAL;
	*out = NULL;
	h = calloc(1, sizeof *h);
	if (!h)
		return COGW_E_NOMEM;
	h->resp = h->evt = h->self = h->evt_self = (mqd_t)-1;
	h->efd = h->epfd = -1;
	for (unsigned i = 0; i < MBX_LINES_MAX; i++)
		h->lines[i].cmd = (mqd_t)-1;
	strcpy(h->instance, o->instance);
	h->pid = getpid();
	h->timeout_ms = o->timeout_ms ? o->timeout_ms : DEFAULT_TIMEOUT_MS;
	pthread_mutex_init(&h->mu, NULL);
	pthread_mutex_init(&h->setup_mu, NULL);
	pthread_condattr_t ca;

	pthread_condattr_init(&ca);
	pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
	pthread_cond_init(&h->cond, &ca);
	pthread_cond_init(&h->reader_cond, &ca);
	pthread_cond_init(&h->setup_cond, &ca);
	pthread_condattr_destroy(&ca);
	/* one call: the first correlation id and the queue names' random part */
	if (getrandom(rnd, sizeof rnd, GRND_NONBLOCK) != (ssize_t)sizeof rnd)
		rnd[2] = (uint32_t)mono_us();
	memcpy(&h->next_corr, rnd, sizeof h->next_corr);
	h->next_corr &= 0x0000FFFFFFFFFFFFull; /* readable, never wraps */

	mode = o->queue_mode ? o->queue_mode : 0600;
	rdepth = o->resp_depth ? o->resp_depth : 32;
	edepth = o->event_depth ? o->event_depth : 32;
	msgsize = o->msg_size ? o->msg_size : MBX_MSG_DEFAULT;
	if (msgsize < MBX_MSG_MIN || msgsize > MBX_MSG_MAX) {
		rc = COGW_E_INVAL;
		goto fail;
	}
	for (int tries = 0; tries < 8; tries++) {
		if (tries) {
			rnd[2] = (uint32_t)mono_us();
			getrandom(&rnd[2], sizeof rnd[2], GRND_NONBLOCK);
		}
		snprintf(h->resp_name, sizeof h->resp_name, "/cogw.%s.c%d.%08x.resp", h->instance,
			 (int)h->pid, rnd[2]);
		snprintf(h->evt_name, sizeof h->evt_name, "/cogw.%s.c%d.%08x.evt", h->instance,
			 (int)h->pid, rnd[2]);
		/* blocking: the leader waits in mq_timedreceive */
		h->resp = make_queue(h->resp_name, mode, rdepth, msgsize, O_RDONLY);
		if (h->resp == (mqd_t)-1 && errno == EINVAL && !clamped) {
			clamp_to_system(&rdepth, &edepth, &msgsize);
			clamped = true;
			h->resp = make_queue(h->resp_name, mode, rdepth, msgsize, O_RDONLY);
		}
		if (h->resp != (mqd_t)-1 || errno != EEXIST)
			break;
	}
	if (h->resp == (mqd_t)-1) {
		rc = queue_create_error();
		goto fail;
	}
	/* created (O_EXCL) with exactly these attributes: no mq_getattr */
	h->resp_msg = msgsize;
	h->resp_depth = rdepth;
	/* blocking: cogw_recv() waits in mq_timedreceive when only events can come */
	h->evt = make_queue(h->evt_name, mode, edepth, msgsize, O_RDONLY);
	if (h->evt == (mqd_t)-1 && errno == EINVAL && !clamped) {
		clamp_to_system(&rdepth, &edepth, &msgsize);
		h->evt = make_queue(h->evt_name, mode, edepth, msgsize, O_RDONLY);
	}
	if (h->evt == (mqd_t)-1) {
		rc = queue_create_error();
		goto fail;
	}
	h->evt_msg = msgsize;
	h->lead_buf = malloc(h->resp_msg);
	if (!h->lead_buf) {
		rc = COGW_E_NOMEM;
		goto fail;
	}
	*out = h;
	return 0;
fail : {
	int e = errno;

	cogw_close(h);
	errno = e;
}
	return rc;
}

void cogw_close(cogw *h)
{
	if (!h)
		return;
	/* Say goodbye to every line (no answer wanted), so the daemon frees
	 * the slot now rather than at the next liveness check. */
	for (unsigned i = 0; i < MBX_LINES_MAX; i++)
		if (h->lines[i].registered)
			send_cmd(h, i, MBX_CMD_UNREGISTER, MBX_F_NO_REPLY, 0, NULL, 0, NULL, 0,
				 mono_us() + 200000u);

	pthread_mutex_lock(&h->mu);
	h->closing = true;
	bool helper = h->reader_started;

	pthread_cond_broadcast(&h->cond);
	pthread_cond_signal(&h->reader_cond);
	pthread_mutex_unlock(&h->mu);
	if (helper) {
		/* wake it if it leads (if the queue is full it wakes anyway) */
		mq_send(h->self, "", 0, 0);
		pthread_join(h->reader, NULL);
	}
	for (unsigned i = 0; i < MBX_LINES_MAX; i++) {
		if (h->lines[i].cmd != (mqd_t)-1)
			mq_close(h->lines[i].cmd);
		h->lines[i].cmd = (mqd_t)-1;
		h->lines[i].registered = false;
	}
	while (h->asyncs) {
		async_op *a = h->asyncs;

		h->asyncs = a->next;
		free(a->data);
		free(a);
	}
	while (h->ring_count) {
		free(h->ring[h->ring_head].data);
		h->ring_head = (h->ring_head + 1) % ASYNC_RING;
		h->ring_count--;
	}
	if (h->epfd >= 0)
		close(h->epfd);
	if (h->efd >= 0)
		close(h->efd);
	if (h->self != (mqd_t)-1)
		mq_close(h->self);
	if (h->evt_self != (mqd_t)-1)
		mq_close(h->evt_self);
	if (h->resp != (mqd_t)-1) {
		mq_close(h->resp);
		mq_unlink(h->resp_name);
	}
	if (h->evt != (mqd_t)-1) {
		mq_close(h->evt);
		mq_unlink(h->evt_name);
	}
	free(h->lead_buf);
	pthread_cond_destroy(&h->cond);
	pthread_cond_destroy(&h->reader_cond);
	pthread_mutex_destroy(&h->mu);
	pthread_cond_destroy(&h->setup_cond);
	pthread_mutex_destroy(&h->setup_mu);
	free(h);
}

/* ---- asynchronous interface -------------------------------------------------------- */

int cogw_send_async(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		    uint64_t *corr)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(cmd);
	uint64_t deadline;
	async_op *a;
	size_t flen;
	int rc;

	if (!h || !ci || (ci->flags & MBX_CI_SERVER) || (len && !payload))
		return COGW_E_INVAL;
	flen = (ci->flags & MBX_CI_DATA) ? ci->fixed : len;
	if (len < flen)
		return COGW_E_INVAL;
	uint64_t now = mono_us();

	deadline = now + (uint64_t)h->timeout_ms * 1000u;
	rc = line_ready(h, line, now, deadline);
	if (rc == 0) /* the helper reads answers nobody waits for */
		rc = helper_ensure(h);
	if (rc)
		return rc;
	a = calloc(1, sizeof *a);
	if (!a)
		return COGW_E_NOMEM;
	uint64_t id = corr_new(h);

	a->corr = id;
	a->line = (uint8_t)line;
	a->code = cmd;
	pthread_mutex_lock(&h->mu);
	a->next = h->asyncs;
	h->asyncs = a;
	pthread_cond_signal(&h->reader_cond); /* its answer needs a reader */
	if (h->evt_waiters)                   /* its answer will not come on the event queue */
		mq_send(h->evt_self, "", 0, 0);
	pthread_mutex_unlock(&h->mu);
	/* a is the reader's from here on: its answer may free it */
	if (corr)
		*corr = id;
	rc = send_cmd(h, line, cmd, 0, id, payload, flen, (const uint8_t *)payload + flen,
		      len - flen, deadline);
	if (rc) {
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
	return rc;
}

int cogw_event_fd(cogw *h)
{
	int rc;

	if (!h)
		return COGW_E_INVAL;
	pthread_mutex_lock(&h->mu);
	rc = event_fds_open(h);
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

static bool ring_pop(cogw *h, cogw_msg *m)
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
static int event_pop(cogw *h, cogw_msg *m, uint8_t *buf, uint64_t now, uint64_t until_us)
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
	got = event_pop(h, m, buf, now, *direct ? slice : 0);
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

		if (ring_pop(h, m))
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
	/* a receiver is long-lived: the helper cuts its waits when the wall
	 * clock steps and keeps it registered across daemon restarts */
	rc = helper_ensure(h);
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

void cogw_get_stats(cogw *h, cogw_stats *st)
{
	pthread_mutex_lock(&h->mu);
	*st = h->stats;
	pthread_mutex_unlock(&h->mu);
}
