/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server.c - the daemon side of one line's mailbox, the top of its
 * files (mailbox/server_int.h names them): create, destroy, the rules, and
 * the loop's two entries, mbx_server_poll() and mbx_server_tick().
 *
 * Design notes (why it looks like this):
 * - One server per line, driven by that line's thread only: the client
 *   table is per line, so a line never waits for a lock another line holds
 *   (docs/architecture.md "Threads and data flow").
 * - Every send to a client is mq_send on an O_NONBLOCK descriptor. A full
 *   client queue means the message is dropped and counted, and the next
 *   message that reaches that queue carries MBX_F_OVERFLOW + the count; an
 *   MBX_EV_OVERFLOW notice follows on the event queue as soon as it has
 *   room. A slow client therefore costs the line one failed syscall per
 *   message, never a stall.
 * - Access control rests on two kernel facts: the owner of a message queue
 *   is the user that created it (fstat on the mqd gives st_uid on Linux),
 *   and a queue with mode 0600 can be read only by that user. The server
 *   sends a random 64-bit token in the REGISTER answer to the response
 *   queue; every later command must carry it. So a process can only act as
 *   a client whose response queue it can read, and it is granted the rights
 *   of that queue's owner. Naming somebody else's queue in REGISTER gains
 *   nothing (the token goes to that queue).
 * - No allocation after create: the client table, the transfer slots and
 *   both message buffers are sized from the config. A transfer slot's
 *   buffer is address space: a transfer pays its size from the budget
 *   shared by all lines before it touches the buffer, and gives the pages
 *   beyond MBX_BUFFER_KEEP back when it ends (mailbox/budget.h), so what
 *   transfers pin is bounded by the budget, not by max_transfer x slots.
 */
#include "mailbox/server_int.h"

#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

/* A tick later than this past the time it asked for means this thread (or
 * the whole machine) stood still: see srv_forgive_late_wake (server_clients.c). */
#define LATE_WAKE_US 100000u

int mbx_server_poll(mbx_server *srv, uint64_t now_us)
{
	int n = 0;

	srv->now_us = now_us;
	while ((unsigned)n < srv->cfg.poll_budget) {
		ssize_t r = mq_receive(srv->q, (char *)srv->rx, srv->rx_size, NULL);

		if (r < 0) {
			if (errno == EAGAIN)
				break;
			if (errno == EINTR)
				continue;
			return -errno;
		}
		n++;
		srv_handle_msg(srv, srv->rx, (size_t)r);
	}
	return n;
}

uint64_t mbx_server_tick(mbx_server *srv, uint64_t now_us)
{
	uint64_t next;
	bool full = now_us >= srv->next_check_us;

	if (srv->wake_by_us != UINT64_MAX && now_us > srv->wake_by_us + LATE_WAKE_US)
		srv_forgive_late_wake(srv, now_us);
	srv->now_us = now_us;
	if (full)
		srv->next_check_us = now_us + (uint64_t)srv->cfg.check_ms * 1000u;
	next = min64(srv_xfers_tick(srv, now_us), srv_clients_tick(srv, now_us, full));
	if (srv->stats.clients)
		next = min64(next, srv->next_check_us);
	srv->wake_by_us = next;
	return next;
}

static void queue_defaults(mbx_server_config *c)
{
	if (!c->queue_mode)
		c->queue_mode = 0620;
	if (!c->depth)
		c->depth = 64;
	if (!c->msg_size)
		c->msg_size = MBX_MSG_DEFAULT;
	if (!c->poll_budget)
		c->poll_budget = c->depth;
}

static void client_defaults(mbx_server_config *c)
{
	if (!c->max_clients)
		c->max_clients = 16;
	if (!c->check_ms)
		c->check_ms = 1000;
	if (!c->register_timeout_ms)
		c->register_timeout_ms = 10000;
	if (!c->max_clients_per_uid)
		c->max_clients_per_uid = c->max_clients / 4 ? c->max_clients / 4 : 1;
	/* at least one slot for writers (a table of 2 or 3 included): the
	 * rule "a reader never makes a writer's REGISTER fail with FULL" */
	if (!c->write_reserve && c->max_clients >= 2)
		c->write_reserve = c->max_clients / 4 ? c->max_clients / 4 : 1;
	if (!c->max_outstanding)
		c->max_outstanding = 16;
	if (!c->read_outstanding)
		c->read_outstanding = 32;
	if (!c->max_request_timeout_ms)
		c->max_request_timeout_ms = 60000;
}

static void xfer_defaults(mbx_server_config *c)
{
	if (!c->xfer_slots)
		c->xfer_slots = 2;
	if (!c->max_transfer)
		c->max_transfer = 1u << 20;
	if (!c->xfer_timeout_ms)
		c->xfer_timeout_ms = 5000;
	if (!c->xfer_per_client)
		c->xfer_per_client = c->xfer_slots / 2 ? c->xfer_slots / 2 : 1;
	if (!c->xfer_max_ms)
		c->xfer_max_ms = 60000;
}

/* The documented default of every limit left 0 in the config. */
static void config_fill_defaults(mbx_server_config *c)
{
	queue_defaults(c);
	client_defaults(c);
	xfer_defaults(c);
	/* A client queue others can read leaks the token: never allowed. */
	c->forbidden_client_mode |= 0044;
}

static bool config_is_valid(const mbx_server_config *c)
{
	/* The command queue carries every client's token: only the daemon
	 * may read it (in older daemons, with 0660, any member of the group read the
	 * tokens of other clients and acted with their rights). */
	if (c->queue_mode & ~0777u || c->queue_mode & 0044 ||
	    (c->queue_chown && c->queue_uid != geteuid()))
		return false;
	return c->msg_size >= MBX_MSG_MIN && c->msg_size <= MBX_MSG_MAX &&
	       c->max_clients <= 0xFFFFu && c->xfer_slots <= 255;
}

/* Everything the server will ever use, so that nothing is allocated
 * after create: buffers, the client and transfer tables, room for a
 * reload's access rules (mbx_server_set_rules). */
static int allocate_tables(mbx_server *srv, const mbx_access_rule *rules)
{
	mbx_server_config *c = &srv->cfg;

	srv->rx_size = c->msg_size;
	srv->rx = malloc(srv->rx_size);
	srv->tx = malloc(MBX_MSG_MAX);
	srv->clients = calloc(c->max_clients, sizeof *srv->clients);
	srv->sub_words = (c->max_clients + 63) / 64;
	srv->sub_bits = calloc(32 * srv->sub_words, sizeof *srv->sub_bits);
	srv->xfers = calloc(c->xfer_slots, sizeof *srv->xfers);
	srv->rules_cap = c->n_rules > MBX_SERVER_RULES_MAX ? c->n_rules : MBX_SERVER_RULES_MAX;
	srv->rules = calloc(srv->rules_cap, sizeof *srv->rules);
	if (srv->rules && c->n_rules)
		memcpy(srv->rules, rules, c->n_rules * sizeof *srv->rules);
	if (!srv->rx || !srv->tx || !srv->clients || !srv->sub_bits || !srv->xfers || !srv->rules)
		return -ENOMEM;
	c->rules = srv->rules;
	for (unsigned i = 0; i < c->max_clients; i++)
		srv->clients[i].resp = srv->clients[i].evt = (mqd_t)-1;
	for (unsigned i = 0; i < c->xfer_slots; i++) {
		srv->xfers[i].buf = mbx_buffer_reserve(c->max_transfer);
		if (!srv->xfers[i].buf)
			return -ENOMEM;
	}
	return 0;
}

static int open_command_queue(mbx_server *srv)
{
	const mbx_server_config *c = &srv->cfg;
	struct mq_attr attr = { .mq_maxmsg = c->depth, .mq_msgsize = c->msg_size };
	struct stat qst;

	if (c->unlink_existing)
		mq_unlink(srv->qname);
	srv->q = mq_open(srv->qname, O_CREAT | O_EXCL | O_RDONLY | O_NONBLOCK | O_CLOEXEC,
			 c->queue_mode, &attr);
	if (srv->q == (mqd_t)-1)
		return -errno;
	/* The mode given to mq_open is filtered by the umask: set it
	 * exactly, as the config says. */
	if (fchmod((int)srv->q, c->queue_mode) < 0 ||
	    (c->queue_chown && fchown((int)srv->q, c->queue_uid, c->queue_gid) < 0) ||
	    fstat((int)srv->q, &qst) < 0)
		return -errno;
	srv->q_ino = qst.st_ino;
	return 0;
}

int mbx_server_create(mbx_server **out, const mbx_server_config *cfg)
{
	mbx_server *srv;
	int rc;

	*out = NULL;
	if (!cfg || !cfg->queue_name || cfg->line >= MBX_LINES_MAX ||
	    !mbx_queue_name_is_valid(cfg->queue_name, strlen(cfg->queue_name) + 1) ||
	    (cfg->n_rules && !cfg->rules) || cfg->default_access > MBX_ACCESS_WRITE)
		return -EINVAL;
	srv = calloc(1, sizeof *srv);
	if (!srv)
		return -ENOMEM;
	srv->q = (mqd_t)-1;
	srv->wake_by_us = UINT64_MAX;
	srv->cfg = *cfg;
	config_fill_defaults(&srv->cfg);
	rc = -EINVAL;
	if (!config_is_valid(&srv->cfg))
		goto fail;
	strcpy(srv->qname, cfg->queue_name);
	srv->cfg.queue_name = srv->qname;
	rc = allocate_tables(srv, cfg->rules);
	if (rc)
		goto fail;
	if (getrandom(&srv->rng, sizeof srv->rng, GRND_NONBLOCK) != (ssize_t)sizeof srv->rng)
		srv->rng = (uint64_t)getpid() * 0x9E3779B97F4A7C15ull ^ (uint64_t)(uintptr_t)srv;
	rc = open_command_queue(srv);
	if (rc)
		goto fail;
	*out = srv;
	return 0;
fail:
	mbx_server_destroy(srv);
	return rc;
}

void mbx_server_destroy(mbx_server *srv)
{
	if (!srv)
		return;
	if (srv->clients) {
		for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
			if (srv->clients[i].resp != (mqd_t)-1)
				mq_close(srv->clients[i].resp);
			if (srv->clients[i].evt != (mqd_t)-1)
				mq_close(srv->clients[i].evt);
		}
	}
	if (srv->xfers)
		for (unsigned i = 0; i < srv->cfg.xfer_slots; i++)
			mbx_buffer_free(srv->xfers[i].buf, srv->cfg.max_transfer);
	if (srv->q != (mqd_t)-1) {
		mq_close(srv->q);
		mq_unlink(srv->qname);
	}
	free(srv->xfers);
	free(srv->clients);
	free(srv->sub_bits);
	free(srv->rules);
	free(srv->tx);
	free(srv->rx);
	free(srv);
}

int mbx_server_fd(const mbx_server *srv)
{
	return (int)srv->q;
}

int mbx_server_set_rules(mbx_server *srv, const mbx_access_rule *rules, size_t n_rules,
			 uint8_t default_access)
{
	if (n_rules > srv->rules_cap || (n_rules && !rules) || default_access > MBX_ACCESS_WRITE)
		return -EINVAL;
	if (n_rules)
		memcpy(srv->rules, rules, n_rules * sizeof *srv->rules);
	srv->cfg.n_rules = n_rules;
	srv->cfg.default_access = default_access;
	/* Access is granted at REGISTER; a reload that revokes a right must
	 * reach the clients already registered too, or it would not take
	 * effect until they reconnect. A client left with no access at all
	 * is dropped (it would be refused registration now). */
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id)
			continue;
		c->access = srv_access_of(srv, c->uid);
		if (c->access == MBX_ACCESS_NONE) {
			srv->stats.access_denied++;
			srv_client_remove(srv, c, true);
		}
	}
	return 0;
}

void mbx_server_set_lease(mbx_server *srv, unsigned lease_ms)
{
	srv->cfg.lease_ms = lease_ms;
	/* Every client gets a full new lease: one computed with the old
	 * value (0 = none) would expire at once. */
	for (unsigned i = 0; i < srv->cfg.max_clients; i++)
		if (srv->clients[i].id)
			srv_lease_renew(srv, &srv->clients[i], srv->now_us);
}

size_t mbx_server_buffer_bytes(const mbx_server *srv)
{
	return (size_t)srv->cfg.xfer_slots * (srv->cfg.max_transfer + sizeof *srv->xfers) +
	       srv->rx_size + MBX_MSG_MAX + srv->cfg.max_clients * sizeof *srv->clients +
	       srv->rules_cap * sizeof *srv->rules;
}

const mbx_server_stats *mbx_server_stats_get(const mbx_server *srv)
{
	return &srv->stats;
}
