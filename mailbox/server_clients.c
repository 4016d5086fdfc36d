/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_clients.c - the lifetime of a registered client: its
 * lease, the checks that find a dead one (its process or its queues gone),
 * its removal (with its transfers, subscriptions and, when provably
 * orphaned, its queues), and what the line may ask about the clients.
 */
#include "mailbox/server_int.h"

#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <signal.h>
#include <string.h>
#include <sys/stat.h>

void srv_client_remove(mbx_server *srv, mbx_client *c, bool reaped)
{
	uint32_t id = c->id;

	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		/* HELD slots stay: the glue may still point an SDO transfer
		 * at their data; answering the request frees them. */
		if (x->client == id && (x->st == XS_IN || x->st == XS_OUT)) {
			srv->stats.xfer_failed++;
			srv_xfer_free(srv, x);
		}
	}
	if (c->resp != (mqd_t)-1)
		mq_close(c->resp);
	if (c->evt != (mqd_t)-1)
		mq_close(c->evt);
	memset(c, 0, sizeof *c);
	c->resp = c->evt = (mqd_t)-1;
	srv_sub_index_update(srv, c);
	srv->stats.clients--;
	if (reaped)
		srv->stats.clients_reaped++;
	else
		srv->stats.clients_unregistered++;
	if (srv->cfg.dispatch.client_gone)
		srv->cfg.dispatch.client_gone(srv->cfg.dispatch_ctx, srv, id);
}

/* Is the queue behind name still the one we hold open? An unlinked (or
 * unlinked and re-created) queue means the client went away. */
static bool queue_still_there(const char *name, ino_t ino)
{
	mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
	struct stat st;
	bool same;

	if (q == (mqd_t)-1)
		return errno != ENOENT; /* EACCES & co: cannot tell, assume ok */
	same = fstat((int)q, &st) == 0 && st.st_ino == ino;
	mq_close(q);
	return same;
}

/* The process of a reaped client is gone: remove its queues too, so that a
 * crashed client does not leave its names (and kernel memory, counted in
 * its owner's RLIMIT_MSGQUEUE) behind. Only a queue that is still the very
 * one the client registered is removed, never a newcomer's of that name.
 *
 * REGISTER is sent by a process the daemon cannot see, so the queues are
 * removed only when they provably belonged to the dead process: the entry
 * was confirmed (whoever used it read the token, i.e. could read the
 * response queue, i.e. is its owner) and its pid was, at REGISTER, a live
 * process of that owner (pid_check). Anybody else naming those queues, a
 * dead pid or somebody else's pid (in older daemons that unlinked other
 * clients' queues and its own command queues) unlinks nothing. */
static void unlink_orphan_queues(const mbx_client *c)
{
	if (!c->confirmed || !c->pid_proven || c->pid_disputed)
		return;
	if (kill((pid_t)c->pid, 0) == 0 || errno != ESRCH)
		return;
	if (queue_still_there(c->resp_name, c->resp_ino))
		mq_unlink(c->resp_name);
	if (queue_still_there(c->evt_name, c->evt_ino))
		mq_unlink(c->evt_name);
}

/* A full lease from now (any command renews it; 0 = no lease, never read). */
void srv_lease_renew(const mbx_server *srv, mbx_client *c, uint64_t now_us)
{
	c->lease_until = now_us + (uint64_t)srv->cfg.lease_ms * 1000u;
}

static bool client_is_dead(const mbx_server *srv, const mbx_client *c, uint64_t now_us,
			   bool full_check)
{
	if (c->dead)
		return true;
	if (srv->cfg.lease_ms && now_us > c->lease_until)
		return true;
	if (!c->confirmed &&
	    now_us > c->registered_us + (uint64_t)srv->cfg.register_timeout_ms * 1000u)
		return true;
	if (!full_check)
		return false;
	if (!c->pid_disputed && kill((pid_t)c->pid, 0) < 0 && errno == ESRCH)
		return true;
	return !queue_still_there(c->resp_name, c->resp_ino) ||
	       !queue_still_there(c->evt_name, c->evt_ino);
}

/* A client's silence is judged only by a server that was awake to hear it.
 * Woken late - this thread, the daemon or the whole machine stood still (a
 * paused VM, a stopped process, an overloaded box) - the renewals it missed
 * may simply not have run yet: every lapsed lease and registration window
 * starts again, once per late wake. A client whose process is gone is still
 * dropped by the next full check. */
void srv_forgive_late_wake(mbx_server *srv, uint64_t now_us)
{
	const uint64_t reg_us = (uint64_t)srv->cfg.register_timeout_ms * 1000u;

	srv->stats.late_wakes++;
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id)
			continue;
		if (srv->cfg.lease_ms && now_us > c->lease_until)
			srv_lease_renew(srv, c, now_us);
		if (!c->confirmed && now_us > c->registered_us + reg_us)
			c->registered_us = now_us;
	}
}

int mbx_server_client_info(const mbx_server *srv, unsigned n, mbx_client_info *info)
{
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		const mbx_client *c = &srv->clients[i];

		if (!c->id || n--)
			continue;
		*info = (mbx_client_info){
			.id = c->id,
			.uid = c->uid,
			.pid = c->pid,
			.access = c->access,
			.confirmed = c->confirmed,
			.classes = c->classes,
			.dropped = c->dropped,
			.pending_drop_events = c->drop_evt,
			.pending_drop_responses = c->drop_resp,
		};
		memcpy(info->resp_queue, c->resp_name, MBX_QNAME_MAX);
		memcpy(info->event_queue, c->evt_name, MBX_QNAME_MAX);
		return 0;
	}
	return -ENOENT;
}

size_t mbx_server_client_max_payload(const mbx_server *srv, uint32_t client)
{
	const mbx_client *c = srv_client_find(srv, client);

	return c ? srv_chunk_size(c) : 0;
}

uint64_t srv_clients_tick(mbx_server *srv, uint64_t now_us, bool full)
{
	const uint64_t reg_us = (uint64_t)srv->cfg.register_timeout_ms * 1000u;
	uint64_t next = UINT64_MAX;

	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id)
			continue;
		if (client_is_dead(srv, c, now_us, full)) {
			unlink_orphan_queues(c);
			srv_client_remove(srv, c, true);
			continue;
		}
		if ((c->drop_evt || c->drop_resp) && !srv_overflow_notice(srv, c))
			next = min64(next, now_us + RETRY_US);
		if (srv->cfg.lease_ms)
			next = min64(next, c->lease_until + 1);
		if (!c->confirmed)
			next = min64(next, c->registered_us + reg_us + 1);
	}
	return next;
}
