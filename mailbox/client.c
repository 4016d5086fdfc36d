/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client.c - libcogw's handle: its life (cogw_open,
 * cogw_loop_open, cogw_close),
 * the top of the transport's files (mailbox/client_transport.h names
 * them). The services (cogw_od_read, cogw_lss, ...) are in
 * mailbox/client_api_*.c and reach the transport only through
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
#include "mailbox/client_transport.h"

#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

_Static_assert((int)COGW_E_NO_MEMORY == (int)MBX_STATUS_MIN,
	       "cogw_err must cover every mbx_status");

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
	case COGW_E_WOULDBLOCK:
		return "not sent: the line's command queue is full or the line registers again"
		       " (retry)";
	case COGW_E_QUEUE_LIMIT:
		return "this user's message-queue memory is used up (RLIMIT_MSGQUEUE:"
		       " raise it with ulimit -q or LimitMSGQUEUE=)";
	}
	return "unknown error";
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

/* A handle with no queue yet: its locks, clocks and first correlation
 * id; *rnd: random bits for the queue names. NULL when out of memory. */
static cogw *handle_new(const cogw_options *o, uint32_t *rnd)
{
	uint32_t bits[3] = { 0 };
	pthread_condattr_t ca;
	cogw *h = calloc(1, sizeof *h);

	if (!h)
		return NULL;
	h->resp = h->evt = h->self = h->evt_self = (mqd_t)-1;
	h->efd = h->epfd = -1;
	for (unsigned i = 0; i < MBX_LINES_MAX; i++)
		h->lines[i].cmd = (mqd_t)-1;
	strcpy(h->instance, o->instance);
	h->pid = getpid();
	h->timeout_ms = o->timeout_ms ? o->timeout_ms : DEFAULT_TIMEOUT_MS;
	pthread_mutex_init(&h->mu, NULL);
	pthread_mutex_init(&h->setup_mu, NULL);
	pthread_condattr_init(&ca);
	pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
	pthread_cond_init(&h->cond, &ca);
	pthread_cond_init(&h->reader_cond, &ca);
	pthread_cond_init(&h->setup_cond, &ca);
	pthread_condattr_destroy(&ca);
	/* one call: the first correlation id and the queue names' random part */
	if (getrandom(bits, sizeof bits, GRND_NONBLOCK) != (ssize_t)sizeof bits)
		bits[2] = (uint32_t)mono_us();
	memcpy(&h->next_corr, bits, sizeof h->next_corr);
	h->next_corr &= 0x0000FFFFFFFFFFFFull; /* readable, never wraps */
	*rnd = bits[2];
	return h;
}

/* The sizes of the handle's queues, from the options or their defaults. */
struct queue_sizes {
	unsigned mode, rdepth, edepth, msgsize;
	bool clamped; /* to the system's limits already */
};

static struct queue_sizes queue_sizes_of(const cogw_options *o)
{
	return (struct queue_sizes){ .mode = o->queue_mode ? o->queue_mode : 0600,
				     .rdepth = o->resp_depth ? o->resp_depth : 32,
				     .edepth = o->event_depth ? o->event_depth : 32,
				     .msgsize = o->msg_size ? o->msg_size : MBX_MSG_DEFAULT };
}

/* The response queue, under a fresh random name (another handle of this
 * pid may hold the first one). */
static int resp_queue_create(cogw *h, struct queue_sizes *qs, uint32_t rnd)
{
	for (int tries = 0; tries < 8; tries++) {
		if (tries) {
			rnd = (uint32_t)mono_us();
			getrandom(&rnd, sizeof rnd, GRND_NONBLOCK);
		}
		snprintf(h->resp_name, sizeof h->resp_name, "/cogw.%s.c%d.%08x.resp", h->instance,
			 (int)h->pid, rnd);
		snprintf(h->evt_name, sizeof h->evt_name, "/cogw.%s.c%d.%08x.evt", h->instance,
			 (int)h->pid, rnd);
		/* blocking: the leader waits in mq_timedreceive */
		h->resp = make_queue(h->resp_name, qs->mode, qs->rdepth, qs->msgsize, O_RDONLY);
		if (h->resp == (mqd_t)-1 && errno == EINVAL && !qs->clamped) {
			clamp_to_system(&qs->rdepth, &qs->edepth, &qs->msgsize);
			qs->clamped = true;
			h->resp = make_queue(h->resp_name, qs->mode, qs->rdepth, qs->msgsize,
					     O_RDONLY);
		}
		if (h->resp != (mqd_t)-1 || errno != EEXIST)
			break;
	}
	if (h->resp == (mqd_t)-1)
		return queue_create_error();
	/* created (O_EXCL) with exactly these attributes: no mq_getattr */
	h->resp_msg = qs->msgsize;
	h->resp_depth = qs->rdepth;
	return 0;
}

/* The event queue, named after the response queue. */
static int evt_queue_create(cogw *h, struct queue_sizes *qs)
{
	/* blocking: cogw_recv() waits in mq_timedreceive when only events can come */
	h->evt = make_queue(h->evt_name, qs->mode, qs->edepth, qs->msgsize, O_RDONLY);
	if (h->evt == (mqd_t)-1 && errno == EINVAL && !qs->clamped) {
		clamp_to_system(&qs->rdepth, &qs->edepth, &qs->msgsize);
		h->evt = make_queue(h->evt_name, qs->mode, qs->edepth, qs->msgsize, O_RDONLY);
	}
	if (h->evt == (mqd_t)-1)
		return queue_create_error();
	h->evt_msg = qs->msgsize;
	return 0;
}

int cogw_open_opts(cogw **out, const cogw_options *o)
{
	struct queue_sizes qs;
	uint32_t rnd;
	cogw *h;
	int rc;

	if (!out || !o || !mbx_instance_is_valid(o->instance))
		return COGW_E_INVAL;
	*out = NULL;
	h = handle_new(o, &rnd);
	if (!h)
		return COGW_E_NOMEM;
	qs = queue_sizes_of(o);
	rc = qs.msgsize < MBX_MSG_MIN || qs.msgsize > MBX_MSG_MAX ? COGW_E_INVAL : 0;
	if (rc == 0)
		rc = resp_queue_create(h, &qs, rnd);
	if (rc == 0)
		rc = evt_queue_create(h, &qs);
	if (rc == 0) {
		h->lead_buf = malloc(h->resp_msg);
		rc = h->lead_buf ? 0 : COGW_E_NOMEM;
	}
	if (rc == 0) {
		*out = h;
		return 0;
	}
	int e = errno;

	cogw_close(h);
	errno = e;
	return rc;
}

int cogw_loop_open(cogw **out, const cogw_options *o)
{
	int rc = cogw_open_opts(out, o);

	if (rc == 0) {
		rc = client_loop_setup(*out);
		if (rc) {
			int e = errno;

			cogw_close(*out);
			*out = NULL;
			errno = e;
		}
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
			client_send_cmd(h, i, MBX_CMD_UNREGISTER, MBX_F_NO_REPLY, 0, NULL, 0, NULL,
					0, mono_us() + 200000u);

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
	free(h->loop_buf);
	pthread_cond_destroy(&h->cond);
	pthread_cond_destroy(&h->reader_cond);
	pthread_mutex_destroy(&h->mu);
	pthread_cond_destroy(&h->setup_cond);
	pthread_mutex_destroy(&h->setup_mu);
	free(h);
}

void cogw_get_stats(cogw *h, cogw_stats *st)
{
	pthread_mutex_lock(&h->mu);
	*st = h->stats;
	pthread_mutex_unlock(&h->mu);
}
