/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/server.c - the gateway's sockets and its one epoll loop.
 *
 * Why nothing a peer does holds up the others: every socket is
 * non-blocking; a connection's input is read only while it has room for
 * another command (max_outstanding) and while its unread answers stay
 * below max_output, so a flooding peer is simply not read (the kernel's
 * socket buffer pushes back on it) and a peer that never reads stops being
 * served, alone; a line longer than max_line is answered ERROR: 600 and
 * skipped to its end without being stored; a peer that sends half a line
 * and goes silent holds only its own buffer. Mailbox replies come through
 * libcogw's loop descriptor in the same loop (cogw_loop_recv: the answer
 * is taken from the response queue in this wake-up, no helper thread in
 * between, docs/fastpath.md); a line whose command queue is full waits
 * for room on that queue's descriptor, without holding up the others.
 */
#include "apps/cogw-ascii/gateway.h"

#include "apps/common/mbx_loop.h"

#include <errno.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <unistd.h>

#define TAG_MAILBOX 1u
#define TAG_SIGNAL 2u
#define TAG_LISTEN 16u /* + listener index */
#define TAG_ROOM 32u   /* + line: its command queue has room */
#define TAG_MAX 64u    /* below: fixed descriptors; above: a conn pointer */

/* The longest a line refused although its queue was writable waits for
 * its next try (a re-registration after a daemon restart takes one round
 * trip). */
#define RETRY_PAUSE_MS 20

/* ---- connections -------------------------------------------------------------- */

static void conn_close(gateway *g, conn *c)
{
	session_conn_gone(g, c);
	epoll_ctl(g->epfd, EPOLL_CTL_DEL, c->fd, NULL);
	close(c->fd);
	for (conn **pp = &g->conns; *pp; pp = &(*pp)->next) {
		if (*pp == c) {
			*pp = c->next;
			break;
		}
	}
	g->n_conns--;
	g->st.closed++;
	if (g->verbose)
		fprintf(stderr, "cogw-ascii: connection %u closed\n", c->id);
	free(c->in);
	free(c->out);
	free(c->slots);
	free(c);
}

static void conn_send(conn *c)
{
	while (conn_pending_out(c)) {
		ssize_t n = send(c->fd, c->out + c->out_off, conn_pending_out(c), MSG_NOSIGNAL);

		if (n < 0) {
			if (errno == EINTR)
				continue;
			if (errno != EAGAIN && errno != EWOULDBLOCK)
				c->dead = true;
			return;
		}
		c->out_off += (size_t)n;
	}
	c->out_off = c->out_len = 0;
}

static bool can_take_command(const gateway *g, const conn *c)
{
	return c->count < g->cfg.max_outstanding && conn_pending_out(c) < g->cfg.max_output;
}

/* Complete lines in c->in become commands while c can take them. */
static void conn_lines(gateway *g, conn *c)
{
	size_t start = 0;

	while (!c->dead && can_take_command(g, c)) {
		char *nl = memchr(c->in + start, '\n', c->in_len - start);

		if (!nl)
			break;
		size_t end = (size_t)(nl - c->in), len = end - start;

		if (c->discarding) {
			c->discarding = false; /* the end of an overlong line */
		} else {
			bool cr = len > 0 && c->in[start + len - 1] == '\r';

			session_line(g, c, c->in + start, cr ? len - 1 : len);
		}
		start = end + 1;
	}
	if (start) {
		memmove(c->in, c->in + start, c->in_len - start);
		c->in_len -= start;
	}
	if (c->in_len > g->cfg.max_line + 1 && !memchr(c->in, '\n', c->in_len)) {
		/* longer than max_line (and its CR LF): answered now, skipped to its end */
		g->st.overlong++;
		c->in_len = 0;
		if (!c->discarding)
			session_refuse(g, c, ASCII_E_MEMORY);
		c->discarding = true;
	}
}

static void conn_arm(gateway *g, conn *c)
{
	bool want_in = !c->eof && can_take_command(g, c);
	bool want_out = conn_pending_out(c) > 0;

	if (want_in == c->reading && want_out == c->writing)
		return;
	struct epoll_event ev = { .events = (want_in ? EPOLLIN : 0u) | (want_out ? EPOLLOUT : 0u),
				  .data.ptr = c };

	if (epoll_ctl(g->epfd, EPOLL_CTL_MOD, c->fd, &ev) < 0)
		c->dead = true;
	c->reading = want_in;
	c->writing = want_out;
}

/* Everything a connection can do now without waiting. */
static void conn_pump(gateway *g, conn *c)
{
	size_t room = g->cfg.max_line + 2;

	c->kick = false;
	for (;;) {
		conn_lines(g, c);
		conn_send(c);
		if (c->dead || c->eof || !can_take_command(g, c))
			break;
		if (c->in_len >= room) /* an overlong line's rest: read over it */
			c->in_len = 0;
		ssize_t n = recv(c->fd, c->in + c->in_len, room - c->in_len, 0);

		if (n > 0) {
			c->in_len += (size_t)n;
			continue;
		}
		if (n == 0)
			c->eof = true;
		else if (errno == EINTR)
			continue;
		else if (errno != EAGAIN && errno != EWOULDBLOCK)
			c->dead = true;
		break;
	}
	if (conn_pending_out(c) >= g->cfg.max_output && !c->slow) {
		c->slow = true; /* counted once: it is no longer read from */
		g->st.slow_readers++;
	}
	if (c->slow && conn_pending_out(c) < g->cfg.max_output)
		c->slow = false;
	if (c->eof && c->count == 0 && !conn_pending_out(c))
		c->dead = true;
	if (c->dead) {
		conn_close(g, c);
		return;
	}
	conn_arm(g, c);
}

static uint8_t access_of_uid(const gateway *g, uid_t uid)
{
	const cogw_mailbox_config *m = &g->daemon.mailbox;

	if (uid == 0)
		return COGW_ACCESS_WRITE;
	for (size_t i = 0; i < m->n_rules; i++)
		if (m->rules[i].uid == uid)
			return m->rules[i].access;
	return m->default_access;
}

static void refuse(int fd, const char *line)
{
	if (send(fd, line, strlen(line), MSG_NOSIGNAL | MSG_DONTWAIT) < 0) {
		/* best effort: the peer learns it by the close too */
	}
	close(fd);
}

static void accept_one(gateway *g, unsigned li)
{
	int fd = accept4(g->listen_fd[li], NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
	struct ucred cred = { .pid = 0, .uid = (uid_t)-1, .gid = (gid_t)-1 };
	socklen_t cl = sizeof cred;
	uint8_t access;
	conn *c;

	if (fd < 0)
		return;
	if (g->n_conns >= g->cfg.max_connections) {
		g->st.refused_full++;
		refuse(fd, "ERROR: 102\r\n");
		return;
	}
	if (g->listen_tcp[li]) {
		access = g->cfg.tcp_access;
	} else if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &cl) == 0) {
		access = access_of_uid(g, cred.uid);
	} else {
		access = COGW_ACCESS_NONE;
	}
	if (access == COGW_ACCESS_NONE) {
		g->st.refused_access++;
		refuse(fd, "ERROR: 100\r\n");
		return;
	}
	c = calloc(1, sizeof *c);
	if (c) {
		c->in = malloc(g->cfg.max_line + 2);
		c->slots = calloc(g->cfg.max_outstanding, sizeof *c->slots);
	}
	if (!c || !c->in || !c->slots) {
		if (c) {
			free(c->in);
			free(c->slots);
		}
		free(c);
		refuse(fd, "ERROR: 600\r\n");
		return;
	}
	c->fd = fd;
	c->id = ++g->next_id;
	c->tcp = g->listen_tcp[li];
	c->uid = cred.uid;
	c->pid = cred.pid;
	c->access = access;
	c->net = g->cfg.default_network > 0 ? g->cfg.default_network : -1;
	c->node = -1;
	c->sdo_timeout_ms = g->cfg.sdo_timeout_ms;
	c->sdo_block = g->cfg.sdo_block;
	struct epoll_event ev = { .events = EPOLLIN, .data.ptr = c };

	if (epoll_ctl(g->epfd, EPOLL_CTL_ADD, fd, &ev) < 0) {
		free(c->in);
		free(c->slots);
		free(c);
		close(fd);
		return;
	}
	c->reading = true;
	c->next = g->conns;
	g->conns = c;
	g->n_conns++;
	g->st.accepted++;
	if (g->verbose)
		fprintf(stderr, "cogw-ascii: connection %u (%s, uid %d, pid %d, %s)\n", c->id,
			c->tcp ? "tcp" : "unix", (int)cred.uid, (int)cred.pid,
			access == COGW_ACCESS_WRITE ? "write" : "read");
}

/* SIGHUP: the daemon's access rules again (cogwd reloads them on its own
 * SIGHUP, docs/mailbox.md), applied to the connections already open, as
 * the daemon re-evaluates its registered clients: a revoked right takes
 * effect at once, a peer left with no access is closed. */
static void reload_rules(gateway *g)
{
	cogw_config next;
	char err[512];
	int rc = g->daemon_config_path[0]
			 ? cogw_config_load_file(&next, g->daemon_config_path, err, sizeof err)
			 : cogw_config_load_string(&next, cogw_default_config_json,
						   COGW_DEFAULT_CONFIG_SOURCE, err, sizeof err);

	if (rc) {
		fprintf(stderr, "cogw-ascii: reload refused, the rules stay: %s\n", err);
		return;
	}
	g->daemon.mailbox.default_access = next.mailbox.default_access;
	memcpy(g->daemon.mailbox.rules, next.mailbox.rules, sizeof next.mailbox.rules);
	g->daemon.mailbox.n_rules = next.mailbox.n_rules;
	cogw_config_free(&next);
	for (conn *c = g->conns; c; c = c->next) {
		if (c->tcp)
			continue;
		c->access = access_of_uid(g, c->uid);
		if (c->access == COGW_ACCESS_NONE) {
			c->dead = true;
			c->kick = true;
		}
	}
	fprintf(stderr, "cogw-ascii: access rules reloaded from %s\n",
		g->daemon_config_path[0] ? g->daemon_config_path : "the embedded default");
}

/* ---- the loop ------------------------------------------------------------------ */

/* One answer or event per wake-up: the loop descriptor is level-triggered
 * and stays readable while more waits, and a receive that finds nothing
 * costs two system calls (docs/fastpath.md). */
static void take_mailbox(gateway *g)
{
	cogw_msg m;

	if (cogw_loop_recv(g->h, &m) == 0) {
		session_mailbox(g, &m);
		cogw_msg_release(&m);
	}
}

/* Lines waiting for room: watch their command queue (once, EPOLLONESHOT;
 * the descriptor is another after a daemon restart). The epoll_wait
 * time-out: RETRY_PAUSE_MS while a line waits for its retry, else -1. */
static int watch_rooms(gateway *g)
{
	int pause = -1;

	for (unsigned l = 0; l < COGW_LINES_MAX; l++) {
		if (g->blocked[l] == GW_AGAIN)
			pause = RETRY_PAUSE_MS;
		if (g->blocked[l] != GW_BLOCKED)
			continue;
		int fd = cogw_loop_cmd_fd(g->h, l);
		struct epoll_event ev = { .events = EPOLLOUT | EPOLLONESHOT,
					  .data.u64 = TAG_ROOM + l };

		if (fd < 0)
			continue;
		if (fd == g->armed_fd[l] && epoll_ctl(g->epfd, EPOLL_CTL_MOD, fd, &ev) == 0)
			continue;
		if (g->armed_fd[l] >= 0)
			epoll_ctl(g->epfd, EPOLL_CTL_DEL, g->armed_fd[l], NULL);
		g->armed_fd[l] = epoll_ctl(g->epfd, EPOLL_CTL_ADD, fd, &ev) == 0 ? fd : -1;
	}
	return pause;
}

static int add_fd(gateway *g, int fd, uint64_t tag)
{
	struct epoll_event ev = { .events = EPOLLIN, .data.u64 = tag };

	return epoll_ctl(g->epfd, EPOLL_CTL_ADD, fd, &ev);
}

int server_run(gateway *g)
{
	struct epoll_event evs[64];

	for (unsigned l = 0; l < COGW_LINES_MAX; l++)
		g->armed_fd[l] = -1;
	if (add_fd(g, g->sigfd, TAG_SIGNAL) < 0 || add_fd(g, cogw_loop_fd(g->h), TAG_MAILBOX) < 0) {
		perror("cogw-ascii: epoll set-up");
		return -1;
	}
	for (unsigned i = 0; i < g->n_listen; i++)
		if (add_fd(g, g->listen_fd[i], TAG_LISTEN + i) < 0)
			return -1;
	while (!g->stop) {
		int n = epoll_wait(g->epfd, evs, 64, mbx_loop_wait_ms(g->h, watch_rooms(g)));

		if (n < 0 && errno != EINTR) {
			perror("cogw-ascii: epoll_wait");
			break;
		}
		/* leases, a daemon restart, requests past their time-out */
		cogw_loop_tick(g->h);
		for (int i = 0; i < n; i++) {
			uint64_t tag = evs[i].data.u64;

			if (tag == TAG_MAILBOX) {
				take_mailbox(g);
			} else if (tag == TAG_SIGNAL) {
				struct signalfd_siginfo si;

				while (read(g->sigfd, &si, sizeof si) == sizeof si) {
					if (si.ssi_signo == SIGTERM || si.ssi_signo == SIGINT)
						g->stop = true;
					else if (si.ssi_signo == SIGHUP)
						reload_rules(g);
				}
			} else if (tag >= TAG_ROOM && tag < TAG_MAX) {
				g->blocked[tag - TAG_ROOM] = GW_ROOM;
			} else if (tag >= TAG_LISTEN && tag < TAG_ROOM) {
				accept_one(g, (unsigned)(tag - TAG_LISTEN));
			} else {
				conn *c = evs[i].data.ptr;

				c->kick = true;
				/* all input read and the peer gone both ways: its answers
				 * have nowhere to go (its requests under way finish in the
				 * daemon as orphans); HUP is reported whatever the interest
				 * set, so waiting here would spin */
				if ((evs[i].events & (EPOLLHUP | EPOLLERR)) && c->eof)
					c->dead = true;
			}
		}
		for (unsigned l = 0; l < COGW_LINES_MAX; l++)
			if (g->blocked[l] == GW_AGAIN)
				g->blocked[l] = GW_FREE;
		session_launch(g);
		for (conn *c = g->conns, *next; c; c = next) {
			next = c->next;
			if (c->kick || c->dead)
				conn_pump(g, c);
		}
	}
	while (g->conns)
		conn_close(g, g->conns);
	session_free_all(g);
	return 0;
}
