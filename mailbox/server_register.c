/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_register.c - registration and rights (docs/mailbox.md
 * "Security model"): REGISTER opens the client's two queues, checks
 * their owner and mode, grants the owner's access (the rules), proves the
 * pid, hands out the token, and answers a refusal at most once per
 * interval per owner; re-registration and stale unconfirmed entries.
 */
#include "mailbox/server_int.h"

#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* At most one unsolicited REGISTER answer (a refusal, or the answer of a
 * registration not confirmed yet, again) per this interval to the queues
 * of one user, resp. of one registration: whoever sends REGISTER may not
 * be that user (docs/mailbox.md "Security model"). */
#define REG_ANSWER_INTERVAL_US 100000u

static uint64_t splitmix(uint64_t *s)
{
	uint64_t z = (*s += 0x9E3779B97F4A7C15ull);

	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
	return z ^ (z >> 31);
}

static uint64_t new_token(mbx_server *srv)
{
	uint64_t t = 0;

	/* getrandom never blocks once the pool is initialised (GRND_NONBLOCK
	 * guards early boot); the fallback is unpredictable enough only
	 * against a casual local user, so it is mixed with the clock. */
	if (getrandom(&t, sizeof t, GRND_NONBLOCK) != (ssize_t)sizeof t) {
		struct timespec ts;

		clock_gettime(CLOCK_MONOTONIC, &ts);
		srv->rng ^= (uint64_t)ts.tv_nsec << 17 ^ (uint64_t)ts.tv_sec;
		t = splitmix(&srv->rng);
	}
	return t ? t : 1;
}

uint8_t srv_access_of(const mbx_server *srv, uint32_t uid)
{
	if (uid == 0)
		return MBX_ACCESS_WRITE;
	for (size_t i = 0; i < srv->cfg.n_rules; i++)
		if (srv->rules[i].uid == uid)
			return srv->rules[i].access;
	return srv->cfg.default_access;
}

/* Open a client queue for sending and check it. Returns the mqd or -1 with
 * *status set. */
static mqd_t open_client_queue(mbx_server *srv, const char *name, struct stat *st,
			       struct mq_attr *attr, int *status)
{
	mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);

	if (q == (mqd_t)-1) {
		*status = MBX_E_QUEUE;
		return q;
	}
	if (fstat((int)q, st) < 0 || mq_getattr(q, attr) < 0) {
		*status = MBX_E_QUEUE;
	} else if (st->st_mode & srv->cfg.forbidden_client_mode) {
		*status = MBX_E_ACCESS; /* others could read the token */
	} else if (attr->mq_msgsize < (long)MBX_MSG_MIN) {
		*status = MBX_E_QUEUE;
	} else {
		*status = 0;
		return q;
	}
	mq_close(q);
	return (mqd_t)-1;
}

/* Is pid a live process running as uid (any of its real, effective, saved
 * or file-system uids)? 1 yes, 0 it runs as somebody else, -ESRCH no such
 * process, -EACCES cannot tell (procfs hidden). The process that created
 * a queue had the owner's fs uid then; a pid of another user, or of
 * nobody, is a REGISTER lying about who sent it. Read into a stack buffer
 * with read(2), not through stdio: fopen would allocate its FILE and
 * buffer on the line thread (no malloc after start-up there) and fstat
 * the file to size that buffer (docs/fastpath.md "One-shot `cogwctl`"). */
static int pid_check(uint32_t pid, uint32_t uid)
{
	char path[32], text[1024];
	unsigned long u[4];
	size_t len = 0;
	ssize_t got;
	int rc = -EACCES;

	snprintf(path, sizeof path, "/proc/%u/status", (unsigned)pid);
	int fd = open(path, O_RDONLY | O_CLOEXEC);

	if (fd < 0) {
		if (kill((pid_t)pid, 0) < 0 && errno == ESRCH)
			return -ESRCH;
		return -EACCES;
	}
	/* The Uid: line is the ninth, a few hundred bytes in; read until it
	 * is complete (procfs hands the file out in one read as a rule). */
	const char *uid_line = NULL;

	while (len < sizeof text - 1 && (got = read(fd, text + len, sizeof text - 1 - len)) > 0) {
		len += (size_t)got;
		text[len] = '\0';
		uid_line = strncmp(text, "Uid:", 4) == 0 ? text : strstr(text, "\nUid:");
		if (uid_line && strchr(uid_line + 1, '\n'))
			break;
		uid_line = NULL;
	}
	close(fd);
	if (!uid_line)
		return rc;
	uid_line += *uid_line == '\n' ? 5 : 4;
	if (sscanf(uid_line, "%lu %lu %lu %lu", &u[0], &u[1], &u[2], &u[3]) != 4)
		return rc;
	rc = 0;
	for (int i = 0; i < 4; i++)
		if (u[i] == uid)
			rc = 1;
	return rc;
}

typedef struct reg_queues {
	mqd_t resp, evt;
	struct stat rst, est;
	struct mq_attr rattr, eattr;
} reg_queues;

/* The refusal record of the user uid (the least recently seen one is
 * reused for a newcomer). */
static struct refusal_sender *refusal_sender_of(mbx_server *srv, uint32_t uid)
{
	struct refusal_sender *lru = &srv->refusals[0];

	for (unsigned i = 0; i < REFUSAL_SENDERS; i++) {
		struct refusal_sender *s = &srv->refusals[i];

		if (s->refused && s->uid == uid)
			return s;
		if (!s->refused || (lru->refused && s->seen_us < lru->seen_us))
			lru = s;
	}
	memset(lru, 0, sizeof *lru);
	lru->uid = uid;
	return lru;
}

/* A REGISTER refused, counted for the owner of the queues it named (the
 * only sender identity the kernel confirms). Whoever sent it may be
 * somebody else, so the refusal is written to the response queue only
 * when it is about that owner (its access, its quota, its event queue) -
 * never when the REGISTER's claims do not match the queues - and then at
 * most once per REG_ANSWER_INTERVAL_US per owner: a flood of REGISTERs
 * naming a victim's queues must not become a flood into them. */
static void register_refuse(mbx_server *srv, const reg_queues *q, const mbx_hdr *h, int status,
			    bool about_owner)
{
	struct refusal_sender *s = refusal_sender_of(srv, (uint32_t)q->rst.st_uid);
	mbx_client tmp = { .resp = q->resp,
			   .evt = (mqd_t)-1,
			   .resp_msg = (size_t)q->rattr.mq_msgsize };

	s->refused++;
	s->seen_us = srv->now_us;
	srv->stats.reg_refused++;
	if (status == MBX_E_ACCESS)
		srv->stats.access_denied++;
	if (h->flags & MBX_F_NO_REPLY)
		return;
	if (!about_owner || srv->now_us < s->answered_us) {
		srv->stats.reg_unanswered++;
		return;
	}
	s->answered_us = srv->now_us + REG_ANSWER_INTERVAL_US;
	/* through a temporary client record: the normal send path (size
	 * checks, non-blocking); no token is given */
	srv_send_status(srv, &tmp, h->code, h->corr, status, 0, NULL, 0);
}

/* Do the REGISTER's claims match the queues? 0 or MBX_E_ACCESS: both
 * queues of one owner, the claimed uid that owner, neither queue this
 * line's command queue, and the claimed pid a live process of the owner.
 * *pid_rc: pid_check's answer (1 = proven). */
static int register_identity(const mbx_server *srv, const mbx_register_req *r,
			     const struct stat *rst, const struct stat *est, int *pid_rc)
{
	*pid_rc = -EACCES;
	if (est->st_uid != rst->st_uid || r->uid != (uint32_t)rst->st_uid ||
	    rst->st_ino == srv->q_ino || est->st_ino == srv->q_ino)
		return MBX_E_ACCESS;
	*pid_rc = pid_check(r->pid, r->uid);
	if (*pid_rc == 0 || *pid_rc == -ESRCH)
		return MBX_E_ACCESS; /* not the owner's process */
	return 0;
}

/* The registration already made for this response queue, if any. Who
 * sends REGISTER is unknown (a message queue has no peer credentials), so
 * a used registration is replaced only by a REGISTER that proves to be
 * that client: it carries the entry's id and token in its header (only
 * the reader of the response queue knows them); otherwise it is refused,
 * unanswered (*refused; a stranger's corr must not complete the victim's
 * call). A registration not confirmed yet is returned: the caller
 * answers it again rather than adding a second one for the same queues. */
static mbx_client *register_existing(mbx_server *srv, const mbx_hdr *h, ino_t resp_ino,
				     bool *refused)
{
	*refused = false;
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *o = &srv->clients[i];

		if (!o->id || o->resp_ino != resp_ino)
			continue;
		if (h->client == o->id && h->token == o->token) {
			srv_client_remove(srv, o, false);
			return NULL;
		}
		if (o->confirmed) {
			srv_count_bad(srv, MBX_BAD_CLIENT);
			*refused = true;
			return NULL;
		}
		return o;
	}
	return NULL;
}

/* A legitimate client confirms its registration as soon as it has read
 * the answer; one still unconfirmed after this long may give its slot to
 * a new registration (it may well be somebody else's REGISTER naming
 * queues their owner does not use on this line). */
static uint64_t confirm_grace_us(const mbx_server *srv)
{
	uint64_t half = (uint64_t)srv->cfg.register_timeout_ms * 500u;

	return half < 1000000u ? half : 1000000u;
}

/* The oldest registration past its confirm grace, of uid only when
 * of_uid: NULL if none. */
static mbx_client *stale_unconfirmed(const mbx_server *srv, bool of_uid, uint32_t uid)
{
	mbx_client *old = NULL;

	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id || c->confirmed || (of_uid && c->uid != uid) ||
		    srv->now_us < c->registered_us + confirm_grace_us(srv))
			continue;
		if (!old || c->registered_us < old->registered_us)
			old = c;
	}
	return old;
}

/* A free slot for a client of uid with access, or NULL (*status
 * MBX_E_FULL): one user cannot take every slot, and the last write_reserve
 * slots are for writers: a read-only client flooding REGISTER must not
 * lock a writer out with FULL. Where a limit is reached, the oldest
 * registration still unconfirmed past its grace (of that user, for the
 * per-user limit) gives way. */
static mbx_client *register_slot(mbx_server *srv, uint32_t uid, uint8_t access, int *status)
{
	for (unsigned pass = 0; pass < 2; pass++) {
		unsigned free_slots = 0, of_uid = 0;
		mbx_client *c = NULL;

		for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
			if (!srv->clients[i].id) {
				if (!c)
					c = &srv->clients[i];
				free_slots++;
			} else if (srv->clients[i].uid == uid) {
				of_uid++;
			}
		}
		bool uid_full = uid != 0 && of_uid >= srv->cfg.max_clients_per_uid;
		bool no_room = !c ||
			       (access < MBX_ACCESS_WRITE && free_slots <= srv->cfg.write_reserve);

		if (!uid_full && !no_room)
			return c;
		mbx_client *old = pass == 0 ? stale_unconfirmed(srv, uid_full, uid) : NULL;

		if (!old)
			break;
		srv_client_remove(srv, old, true);
	}
	srv->stats.limited++;
	*status = MBX_E_FULL;
	return NULL;
}

static void client_init(mbx_server *srv, mbx_client *c, const mbx_register_req *r,
			const reg_queues *q, uint8_t access, int pid_rc)
{
	if (++srv->gen == 0)
		srv->gen = 1;
	memset(c, 0, sizeof *c);
	c->id = ((uint32_t)srv->gen << 16) | (uint32_t)(c - srv->clients + 1);
	c->token = new_token(srv);
	c->resp = q->resp;
	c->evt = q->evt;
	c->resp_msg = (size_t)q->rattr.mq_msgsize;
	c->evt_msg = (size_t)q->eattr.mq_msgsize;
	if (c->resp_msg > MBX_MSG_MAX)
		c->resp_msg = MBX_MSG_MAX;
	if (c->evt_msg > MBX_MSG_MAX)
		c->evt_msg = MBX_MSG_MAX;
	c->resp_depth = (unsigned)q->rattr.mq_maxmsg;
	c->resp_ino = q->rst.st_ino;
	c->evt_ino = q->est.st_ino;
	c->uid = (uint32_t)q->rst.st_uid;
	c->pid = r->pid;
	c->pid_proven = pid_rc == 1;
	c->access = access;
	c->registered_us = srv->now_us;
	srv_lease_renew(srv, c, srv->now_us);
	memcpy(c->resp_name, r->resp_queue, MBX_QNAME_MAX);
	memcpy(c->evt_name, r->event_queue, MBX_QNAME_MAX);
	srv->stats.clients++;
	srv->stats.clients_registered++;
	srv->stats.commands_ok++;
}

/* Open both queues named by the request; false (counted, refused where
 * an answer may go) when either cannot be a client queue. */
static bool register_open_queues(mbx_server *srv, const mbx_hdr *h, const mbx_register_req *r,
				 reg_queues *q)
{
	int status;

	q->resp = open_client_queue(srv, r->resp_queue, &q->rst, &q->rattr, &status);
	if (q->resp == (mqd_t)-1) {
		/* nowhere to answer (or must not answer: readable by all) */
		srv_count_bad(srv, MBX_BAD_QUEUE);
		srv->stats.reg_refused++;
		if (status == MBX_E_ACCESS)
			srv->stats.access_denied++;
		return false;
	}
	q->evt = open_client_queue(srv, r->event_queue, &q->est, &q->eattr, &status);
	if (q->evt == (mqd_t)-1) {
		srv_count_bad(srv, MBX_BAD_QUEUE);
		register_refuse(srv, q, h, status, true);
		mq_close(q->resp);
		return false;
	}
	return true;
}

/* The answer that carries the token (NO_REPLY does not apply to it). */
static int register_answer(mbx_server *srv, mbx_client *c, const mbx_hdr *h)
{
	mbx_register_resp out = {
		.token = c->token,
		.client = c->id,
		.lease_ms = srv->cfg.lease_ms,
		.max_msg = srv->cfg.msg_size,
		.max_transfer = srv->cfg.max_transfer,
		.access = c->access,
		.line = srv->cfg.line,
	};

	c->answered_us = srv->now_us;
	return srv_send_status(srv, c, h->code, h->corr, 0, 0, &out, sizeof out);
}

/* Another REGISTER for the queues of a registration not confirmed yet:
 * the same answer (id, token) again, never a second entry, so repeating a
 * user's REGISTER takes no more of that user's quota than the user's own
 * does. At most once per REG_ANSWER_INTERVAL_US (the rest counted). A
 * REGISTER naming another pid makes the pid worthless for liveness and
 * for removing the queues after the client's death. */
static void register_answer_again(mbx_server *srv, mbx_client *c, const mbx_hdr *h,
				  const mbx_register_req *r)
{
	if (r->pid != c->pid)
		c->pid_disputed = true;
	if (srv->now_us < c->answered_us + REG_ANSWER_INTERVAL_US) {
		srv->stats.reg_unanswered++;
		return;
	}
	register_answer(srv, c, h);
}

void srv_handle_register(mbx_server *srv, const mbx_hdr *h, const uint8_t *p)
{
	mbx_register_req r;
	reg_queues q;
	mbx_client *c;
	int status, pid_rc;
	uint8_t access;
	bool used;

	memcpy(&r, p, sizeof r);
	if (!register_open_queues(srv, h, &r, &q))
		return;
	status = register_identity(srv, &r, &q.rst, &q.est, &pid_rc);
	if (status) {
		register_refuse(srv, &q, h, status, false);
		goto close;
	}
	c = register_existing(srv, h, q.rst.st_ino, &used);
	if (used) {
		register_refuse(srv, &q, h, MBX_E_ACCESS, false);
		goto close;
	}
	if (c) {
		register_answer_again(srv, c, h, &r);
		goto close;
	}
	access = srv_access_of(srv, (uint32_t)q.rst.st_uid);
	if (access == MBX_ACCESS_NONE)
		status = MBX_E_ACCESS;
	else
		c = register_slot(srv, (uint32_t)q.rst.st_uid, access, &status);
	if (status) {
		register_refuse(srv, &q, h, status, true);
		goto close;
	}
	client_init(srv, c, &r, &q, access, pid_rc);
	if (register_answer(srv, c, h) < 0)
		srv_client_remove(srv, c, true);
	return;
close:
	mq_close(q.resp);
	mq_close(q.evt);
}
