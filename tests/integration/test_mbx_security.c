/* Attacks on the mailbox, performed as a hostile local process would
 * (docs/mailbox.md "Security model"): an in-process mbx_server on REAL POSIX message queues, a
 * victim client using libcogw in a forked child, and an attacker that is
 * another uid (a forked child that drops to 65534 = nobody, as
 * `setpriv --reuid=65534 --regid=65534 --clear-groups` would) sending raw
 * mailbox messages. Needs root (to change uid and to read every queue's
 * owner, like the daemon); skipped otherwise.
 *
 * Covered:
 *  - REGISTER naming a live client's queues and pid must not replace that
 *    client (it used to: the victim never got an answer again);
 *  - REGISTER naming a pid that does not exist must not make the daemon
 *    unlink the queues it named (the victim's, or the daemon's own
 *    command queue);
 *  - REGISTER with the sender's own queues naming a live process of
 *    another user as its sender must be refused (the Uid: line of
 *    /proc/PID/status), the same naming its own pid registered;
 *  - the command queue carries every client's token: nobody but the
 *    daemon may read it (default mode, and modes with read bits for
 *    group/others refused at create);
 *  - REGISTER naming the command queues of other lines (root's, with pid
 *    1) must register nobody and write nothing into them;
 *  - REGISTER naming another user's queues (swapped, mixed, or a pair it
 *    has not registered yet) must not take that user's quota;
 *  - a flood of REGISTERs whose refusals would go to a victim's queue
 *    must write nothing there (figures printed: refused, dropped, the
 *    victim's slowest call);
 *  - a flood of REGISTERs naming a client's own pair while it registers
 *    must not keep it out, nor must registrations of its pairs that
 *    somebody else made and nobody confirmed;
 *  - the line-lockout attack against cogwd itself, with three lines and
 *    the capability bounding set of etc/cogwd.service (needs vcan0..2).
 */
#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <inttypes.h>
#include <mqueue.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "mailbox/cogw.h"
#include "mailbox/server.h"
#include "tests/integration/support/daemon.h"
#include "unity.h"

#define LINE 2
#define CALL_MS 10000
#define NOBODY 65534u
#define VICTIM_UID 1000u

/* ---- the fake line: answers OD_READ 2000h and OD_WRITE, nothing else ---------- */

#define HELD_MAX 8 /* the fake line's pending table (lines/ has 64) */
#define BIG_ANSWER 8192

typedef struct fake_line {
	unsigned held; /* requests parked in the pending table */
	uint8_t big[BIG_ANSWER];
	pthread_mutex_t mu;
	pthread_t thr;
	volatile bool stop;
	volatile bool running;
	mbx_server *srv;
	unsigned writes_ok;
} fake_line;

static fake_line fl;
static char instance[32];
static char qname[MBX_QNAME_MAX];

static uint64_t now_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void fake_dispatch(void *ctx, mbx_server *srv, const mbx_request *req)
{
	fake_line *f = ctx;
	uint8_t v[4] = { 1, 2, 3, 4 };

	mbx_obj_req o;

	switch (req->code) {
	case MBX_CMD_OD_READ:
		memcpy(&o, req->payload, sizeof o);
		if (o.index == 0x2002) {
			/* never answered: a request "in flight", parked in a
			 * bounded table like the line's pending requests */
			if (f->held >= HELD_MAX)
				mbx_server_respond(srv, &req->reply, MBX_E_BUSY, 0, NULL, 0);
			else
				f->held++;
			return;
		}
		if (o.index == 0x2001) { /* a chunked answer */
			mbx_server_respond(srv, &req->reply, 0, 0, f->big, sizeof f->big);
			return;
		}
		mbx_server_respond(srv, &req->reply, 0, 0, v, sizeof v);
		return;
	case MBX_CMD_SDO_UPLOAD: /* a device that answers at once */
		mbx_server_respond(srv, &req->reply, 0, 0, v, sizeof v);
		return;
	case MBX_CMD_OD_WRITE:
		if (f->held >= HELD_MAX) { /* needs a table entry too */
			mbx_server_respond(srv, &req->reply, MBX_E_BUSY, 0, NULL, 0);
			return;
		}
		f->writes_ok++;
		mbx_server_respond(srv, &req->reply, 0, 0, NULL, 0);
		return;
	default:
		mbx_server_respond(srv, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	}
}

static void *loop_main(void *arg)
{
	fake_line *f = arg;

	f->running = true;
	while (!f->stop) {
		struct pollfd pf = { .fd = mbx_server_fd(f->srv), .events = POLLIN };

		poll(&pf, 1, 2);
		pthread_mutex_lock(&f->mu);
		uint64_t now = now_us();

		mbx_server_poll(f->srv, now);
		mbx_server_tick(f->srv, now);
		pthread_mutex_unlock(&f->mu);
	}
	return NULL;
}

static mbx_server_config base_cfg(void)
{
	return (mbx_server_config){
		.line = LINE,
		.queue_name = qname,
		.queue_mode = 0622, /* any user may send (not read) */
		.depth = 10,
		.msg_size = 1024,
		.max_clients = 8,
		.check_ms = 100,
		.register_timeout_ms = 500,
		.default_access = MBX_ACCESS_WRITE,
		.unlink_existing = true,
		.dispatch = { .dispatch = fake_dispatch },
		.dispatch_ctx = &fl,
	};
}

static void start(const mbx_server_config *cfg)
{
	int rc;

	fl.stop = false;
	fl.running = false;
	fl.writes_ok = 0;
	fl.held = 0;
	rc = mbx_server_create(&fl.srv, cfg);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, strerror(-rc));
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&fl.thr, NULL, loop_main, &fl));
	for (unsigned i = 0; i < 10000 && !fl.running; i++)
		sleep_ms(1);
	TEST_ASSERT_TRUE_MESSAGE(fl.running, "loop thread did not start");
}

static void stop(void)
{
	if (!fl.srv)
		return;
	fl.stop = true;
	pthread_join(fl.thr, NULL);
	mbx_server_destroy(fl.srv);
	fl.srv = NULL;
}

static mbx_server_stats stats(void)
{
	mbx_server_stats st;

	pthread_mutex_lock(&fl.mu);
	st = *mbx_server_stats_get(fl.srv);
	pthread_mutex_unlock(&fl.mu);
	return st;
}

static mbx_client_info client_info(unsigned n)
{
	mbx_client_info ci;

	pthread_mutex_lock(&fl.mu);
	TEST_ASSERT_EQUAL_INT(0, mbx_server_client_info(fl.srv, n, &ci));
	pthread_mutex_unlock(&fl.mu);
	return ci;
}

void setUp(void)
{
	if (geteuid() != 0)
		TEST_IGNORE_MESSAGE("needs root (attacks run as uid 65534)");
	snprintf(instance, sizeof instance, "s%d", (int)getpid());
	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(qname, sizeof qname, instance, LINE));
	fl.srv = NULL;
}

void tearDown(void)
{
	stop();
	mq_unlink(qname);
}

/* ---- processes ------------------------------------------------------------------ */

/* Children report failures as the line number in the exit code (0 = ok):
 * Unity's assertions must not run in a forked child. */
#define CHECK(c)                                                                          \
	do {                                                                              \
		if (!(c)) {                                                               \
			fprintf(stderr, "child %d: %s:%d: %s\n", (int)getpid(), __FILE__, \
				__LINE__, #c);                                            \
			return __LINE__ % 250 + 1;                                        \
		}                                                                         \
	} while (0)

typedef int (*child_fn)(void *arg);

/* fork with the loop thread held off its work (see test_mbx_server.c
 * spawn(): no other thread may be inside the allocator at fork time). */
static pid_t spawn(child_fn fn, void *arg)
{
	pid_t pid;

	fflush(stdout);
	pthread_mutex_lock(&fl.mu);
	pid = fork();
	pthread_mutex_unlock(&fl.mu);
	TEST_ASSERT_TRUE(pid >= 0);
	if (pid == 0)
		_exit(fn(arg));
	return pid;
}

static int reap(pid_t pid)
{
	int st = 0;

	TEST_ASSERT_EQUAL_INT(pid, waitpid(pid, &st, 0));
	if (WIFSIGNALED(st))
		return 1000 + WTERMSIG(st);
	return WEXITSTATUS(st);
}

/* Become uid/gid id with no supplementary groups (setpriv --reuid
 * --regid --clear-groups). */
static int become(unsigned id)
{
	if (setgroups(0, NULL) < 0 || setresgid(id, id, id) < 0 || setresuid(id, id, id) < 0)
		return -1;
	return geteuid() == id && getegid() == id ? 0 : -1;
}

static int become_nobody(void)
{
	return become(NOBODY);
}

typedef struct sync2 {
	int ready[2], go[2];
} sync2;

static void sync_init(sync2 *s)
{
	TEST_ASSERT_EQUAL_INT(0, pipe(s->ready));
	TEST_ASSERT_EQUAL_INT(0, pipe(s->go));
}

static void sync_close(sync2 *s)
{
	close(s->ready[0]);
	close(s->ready[1]);
	close(s->go[0]);
	close(s->go[1]);
}

static void child_ready(sync2 *s)
{
	char c = 'r';

	if (write(s->ready[1], &c, 1) != 1)
		_exit(99);
}

static void child_wait_go(sync2 *s)
{
	char c;

	if (read(s->go[0], &c, 1) != 1)
		_exit(98);
}

static void parent_wait_ready(sync2 *s)
{
	struct pollfd pf = { .fd = s->ready[0], .events = POLLIN };
	char c;

	TEST_ASSERT_EQUAL_INT_MESSAGE(1, poll(&pf, 1, 10000), "child not ready");
	TEST_ASSERT_EQUAL_INT(1, read(s->ready[0], &c, 1));
}

static void parent_go(sync2 *s)
{
	char c = 'g';

	TEST_ASSERT_EQUAL_INT(1, write(s->go[1], &c, 1));
}

/* The victim: a libcogw client (root) that registers, waits while the
 * attack runs, then must still be served. */
static int child_victim(void *arg)
{
	sync2 *s = arg;
	cogw *h;
	uint8_t v[8];
	size_t len = 0;
	uint32_t abort = 0;

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s);
	/* after the attack: the very same registration still works */
	CHECK(cogw_od_read(h, LINE, 0x2000, 0, v, sizeof v, &len, 3000, &abort) == 0);
	CHECK(len == 4 && v[0] == 1);
	cogw_close(h);
	return 0;
}

/* ---- the attacker: raw REGISTER as uid 65534 ------------------------------------- */

typedef struct attack {
	char resp[MBX_QNAME_MAX], evt[MBX_QNAME_MAX];
	uint32_t pid, uid;
	uint32_t first_pid; /* if set: the first REGISTER names this pid */
	unsigned times;
	bool as_owner;   /* flood: claims that match the queues (uid, pid) */
	const char *cmd; /* the command queue sent to (NULL: qname, LINE) */
	uint8_t line;
} attack;

/* Send a's REGISTER (naming uid and pid) to its command queue: 0 or -errno.
 * A full queue is waited out: the line drains it. */
static int send_register(mqd_t cmd, const attack *a, uint64_t corr, uint32_t uid, uint32_t pid)
{
	uint8_t buf[MBX_MSG_MIN];
	mbx_register_req r = { .pid = pid, .uid = uid };
	mbx_hdr h = { .magic = MBX_MAGIC,
		      .version = MBX_VERSION,
		      .kind = MBX_KIND_COMMAND,
		      .code = MBX_CMD_REGISTER,
		      .line = a->cmd ? a->line : LINE,
		      .corr = corr };
	int n;

	memcpy(r.resp_queue, a->resp, sizeof r.resp_queue);
	memcpy(r.event_queue, a->evt, sizeof r.event_queue);
	n = mbx_msg_build(buf, sizeof buf, &h, &r, sizeof r);
	if (n < 0)
		return n;
	return mq_send(cmd, (const char *)buf, (size_t)n, 0) == 0 ? 0 : -errno;
}

static int child_register_as_nobody(void *arg)
{
	const attack *a = arg;
	mqd_t cmd;

	CHECK(become_nobody() == 0);
	cmd = mq_open(a->cmd ? a->cmd : qname, O_WRONLY);
	CHECK(cmd != (mqd_t)-1);
	for (unsigned i = 0; i < a->times; i++)
		CHECK(send_register(cmd, a, 4242 + i, a->uid,
				    i == 0 && a->first_pid ? a->first_pid : a->pid) == 0);
	mq_close(cmd);
	return 0;
}

/* Inode of the queue behind name, 0 if there is none. */
static ino_t queue_ino(const char *name)
{
	mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK);
	struct stat st;
	ino_t ino = 0;

	if (q == (mqd_t)-1)
		return 0;
	if (fstat((int)q, &st) == 0)
		ino = st.st_ino;
	mq_close(q);
	return ino;
}

/* A pid nobody has: past pid_max. */
static uint32_t dead_pid(void)
{
	unsigned long max = 4194304;
	FILE *f = fopen("/proc/sys/kernel/pid_max", "r");

	if (f) {
		if (fscanf(f, "%lu", &max) != 1)
			max = 4194304;
		fclose(f);
	}
	return (uint32_t)max + 1000u;
}

/* ---- 1. registration cannot hijack ----------------------------------------------- */

/* In older daemons: a REGISTER naming the victim's queues and pid replaced
 * the victim's entry; the victim's token died with it and every later
 * call of the victim timed out. */
static void test_register_cannot_replace_a_live_client(void)
{
	mbx_server_config cfg = base_cfg();
	mbx_client_info ci;
	sync2 s;
	pid_t victim;
	attack a = { .times = 3 };

	start(&cfg);
	sync_init(&s);
	victim = spawn(child_victim, &s);
	parent_wait_ready(&s);
	ci = client_info(0);
	TEST_ASSERT_TRUE(ci.confirmed);
	memcpy(a.resp, ci.resp_queue, sizeof a.resp);
	memcpy(a.evt, ci.event_queue, sizeof a.evt);
	a.pid = ci.pid;
	a.uid = ci.uid;
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	sleep_ms(300);
	ci = client_info(0);
	TEST_ASSERT_EQUAL_UINT32_MESSAGE((uint32_t)victim, ci.pid,
					 "the victim's entry was replaced");
	TEST_ASSERT_TRUE(ci.confirmed);
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(victim), "the victim lost its registration");
	sync_close(&s);
}

/* ---- 1. registration cannot destroy ---------------------------------------------- */

/* In older daemons: the entry naming a pid that does not exist was reaped
 * at the next liveness check, and the daemon unlinked the queues it named
 * (the victim's): the victim lost its response queue for good. */
static void test_register_with_dead_pid_unlinks_nothing(void)
{
	mbx_server_config cfg = base_cfg();
	mbx_client_info ci;
	sync2 s;
	pid_t victim;
	attack a = { .times = 2 };
	ino_t rino, eino;

	start(&cfg);
	sync_init(&s);
	victim = spawn(child_victim, &s);
	parent_wait_ready(&s);
	ci = client_info(0);
	rino = queue_ino(ci.resp_queue);
	eino = queue_ino(ci.event_queue);
	TEST_ASSERT_TRUE(rino && eino);
	memcpy(a.resp, ci.resp_queue, sizeof a.resp);
	memcpy(a.evt, ci.event_queue, sizeof a.evt);
	/* first push the victim out (naming its pid), then name a dead one */
	a.first_pid = ci.pid;
	a.pid = dead_pid();
	a.uid = ci.uid;
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	/* several liveness checks and the registration timeout */
	sleep_ms(1200);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(rino, queue_ino(ci.resp_queue),
					 "victim's response queue unlinked");
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(eino, queue_ino(ci.event_queue),
					 "victim's event queue unlinked");
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT(0, reap(victim));
	sync_close(&s);
}

/* In older daemons: with a command queue any user may write (0622), naming
 * the daemon's own command queue as "client queues" with a dead pid made
 * the daemon unlink its command queue: no new client could ever connect. */
static void test_register_cannot_unlink_the_command_queue(void)
{
	mbx_server_config cfg = base_cfg();
	attack a = { .times = 1, .uid = 0 };
	struct mq_attr qa = { .mq_maxmsg = 4, .mq_msgsize = 1024 };
	char other[MBX_QNAME_MAX];
	ino_t ino, other_ino;
	mqd_t oq;

	start(&cfg);
	/* stands for another line's command queue (root, 0622) */
	snprintf(other, sizeof other, "/%s.line3.cmd", instance);
	mq_unlink(other);
	oq = mq_open(other, O_CREAT | O_EXCL | O_RDONLY, 0622, &qa);
	TEST_ASSERT_TRUE(oq != (mqd_t)-1);
	fchmod((int)oq, 0622);
	ino = queue_ino(qname);
	other_ino = queue_ino(other);
	TEST_ASSERT_TRUE(ino != 0 && other_ino != 0);
	memcpy(a.resp, qname, sizeof a.resp);
	memcpy(a.evt, other, sizeof a.evt);
	a.pid = dead_pid();
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	sleep_ms(1200);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(ino, queue_ino(qname),
					 "the daemon's command queue was unlinked");
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(other_ino, queue_ino(other),
					 "another command queue was unlinked");
	mq_close(oq);
	mq_unlink(other);
	TEST_ASSERT_EQUAL_UINT32(0, stats().clients);
}

/* A client that really died still has its queues removed (the reaping
 * that the attacks above must not be able to trigger). */
static int child_register_and_die(void *arg)
{
	cogw *h;

	(void)arg;
	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	_exit(0); /* no cogw_close: the queues stay behind */
}

static void test_dead_client_queues_are_still_removed(void)
{
	mbx_server_config cfg = base_cfg();
	mbx_client_info ci;
	pid_t p;

	start(&cfg);
	p = spawn(child_register_and_die, NULL);
	for (unsigned i = 0; i < 1000 && stats().clients == 0; i++)
		sleep_ms(5);
	ci = client_info(0);
	TEST_ASSERT_EQUAL_INT(0, reap(p));
	for (unsigned i = 0; i < 400 && stats().clients; i++)
		sleep_ms(5);
	TEST_ASSERT_EQUAL_UINT32(0, stats().clients);
	TEST_ASSERT_EQUAL_UINT64(0, queue_ino(ci.resp_queue));
	TEST_ASSERT_EQUAL_UINT64(0, queue_ino(ci.event_queue));
}

/* ---- 2. tokens stay secret -------------------------------------------------------- */

/* In older daemons: the default command queue mode was 0660, so every
 * member of the queue's group could read the queue, and with it every
 * client's token. */
static int child_read_command_queue(void *arg)
{
	mqd_t q;

	(void)arg;
	CHECK(become_nobody() == 0);
	q = mq_open(qname, O_RDONLY | O_NONBLOCK);
	CHECK(q == (mqd_t)-1 && errno == EACCES);
	q = mq_open(qname, O_WRONLY | O_NONBLOCK); /* sending is the point */
	CHECK(q != (mqd_t)-1);
	mq_close(q);
	return 0;
}

static void test_command_queue_is_write_only_for_clients(void)
{
	mbx_server_config cfg = base_cfg();
	struct stat st;

	cfg.queue_mode = 0;     /* the default */
	cfg.queue_chown = true; /* the clients' group: nobody's */
	cfg.queue_uid = 0;
	cfg.queue_gid = NOBODY;
	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, fstat(mbx_server_fd(fl.srv), &st));
	TEST_ASSERT_EQUAL_HEX(0, st.st_mode & 0044);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_read_command_queue, NULL)));
}

static void test_readable_command_queue_modes_are_refused(void)
{
	static const unsigned bad[] = { 0660, 0666, 0777, 0640, 0604, 0624 };
	mbx_server_config cfg = base_cfg();
	mbx_server *srv = NULL;

	for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
		cfg.queue_mode = bad[i];
		TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, mbx_server_create(&srv, &cfg),
					      "a readable command queue");
		TEST_ASSERT_NULL(srv);
		TEST_ASSERT_EQUAL_UINT64(0, queue_ino(qname));
	}
}

/* ---- 3. clients survive a daemon restart ----------------------------------------- */

/* A blocking call in flight when the daemon restarts gets one clear error,
 * an asynchronous one too; then service goes on (registered again). In older
 * daemons every call timed out for ever after a restart. */
static int child_caller(void *arg)
{
	sync2 *s = arg;
	cogw *h;
	uint8_t v[8];
	size_t len = 0;
	uint32_t abort = 0;
	uint64_t corr, t0;
	cogw_msg m;
	mbx_obj_req o = { .index = 0x2002 };

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	CHECK(cogw_send_async(h, LINE, MBX_CMD_OD_READ, &o, sizeof o, &corr) == 0);
	child_ready(s);
	t0 = now_us();
	/* in flight while the daemon goes away and comes back */
	int rc = cogw_od_read(h, LINE, 0x2002, 0, v, sizeof v, &len, CALL_MS, &abort);
	if (rc != COGW_E_RESTARTED)
		fprintf(stderr, "in flight: %s\n", cogw_strerror(rc));
	CHECK(rc == COGW_E_RESTARTED);
	CHECK(now_us() - t0 < 5000000u); /* found out well before the timeout */
	CHECK(cogw_recv(h, &m, CALL_MS) == 0);
	CHECK(m.kind == MBX_KIND_RESPONSE && m.corr == corr && m.status == COGW_E_RESTARTED);
	cogw_msg_release(&m);
	/* then normal service, on a new registration; the restart may be
	 * found out before the new daemon is there: "no daemon" until then */
	for (unsigned i = 0; i < 50; i++) {
		rc = cogw_od_read(h, LINE, 0x2000, 0, v, sizeof v, &len, CALL_MS, &abort);
		if (rc != COGW_E_NO_DAEMON)
			break;
		sleep_ms(100);
	}
	if (rc != 0)
		fprintf(stderr, "after the restart: %s\n", cogw_strerror(rc));
	CHECK(rc == 0);
	CHECK(len == 4 && v[0] == 1);
	CHECK(cogw_od_write(h, LINE, 0x2001, 0, v, 4, CALL_MS, &abort) == 0);
	cogw_close(h);
	return 0;
}

/* An event-only client (a logger) makes no calls: it must get its events
 * again after a restart all the same. */
static int child_logger(void *arg)
{
	sync2 *s = arg;
	cogw *h;
	cogw_msg m;
	int rc;

	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_subscribe(h, LINE, MBX_EVC_EMCY, NULL, 0, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s); /* the daemon restarted */
	for (;;) {
		rc = cogw_recv(h, &m, 8000);
		if (rc || m.kind == MBX_KIND_EVENT)
			break;
		cogw_msg_release(&m);
	}
	if (rc)
		fprintf(stderr, "logger: %s\n", cogw_strerror(rc));
	CHECK(rc == 0 && m.code == MBX_EV_EMCY);
	cogw_msg_release(&m);
	cogw_close(h);
	return 0;
}

static void test_clients_survive_a_daemon_restart(void)
{
	mbx_server_config cfg = base_cfg();
	mbx_ev_emcy e = { .node = 3, .code = 0x8130 };
	sync2 a, b;
	pid_t caller, logger;
	int st = 0;

	start(&cfg);
	sync_init(&a);
	sync_init(&b);
	caller = spawn(child_caller, &a);
	logger = spawn(child_logger, &b);
	parent_wait_ready(&a);
	parent_wait_ready(&b);
	sleep_ms(300); /* the blocking call is under way */
	stop();
	sleep_ms(200);
	start(&cfg);
	parent_go(&b);
	/* publish until the logger got one (it must re-register by itself) */
	for (unsigned i = 0; i < 100; i++) {
		pthread_mutex_lock(&fl.mu);
		mbx_server_publish(fl.srv, MBX_EV_EMCY, 0, &e, sizeof e);
		pthread_mutex_unlock(&fl.mu);
		if (waitpid(logger, &st, WNOHANG) == logger)
			break;
		sleep_ms(100);
	}
	if (waitpid(logger, &st, WNOHANG) == 0) {
		kill(logger, SIGKILL);
		waitpid(logger, &st, 0);
	}
	TEST_ASSERT_TRUE_MESSAGE(WIFEXITED(st) && WEXITSTATUS(st) == 0,
				 "the logger got no event after the restart");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(caller), "the caller did not recover");
	TEST_ASSERT_EQUAL_UINT(1, fl.writes_ok);
	sync_close(&a);
	sync_close(&b);
}

/* ---- 5. per-user and per-client limits ------------------------------------------- */

/* A raw client of whoever runs it, with small queues. */
typedef struct rawc {
	char rn[MBX_QNAME_MAX], en[MBX_QNAME_MAX];
	mqd_t cmd, resp, evt;
	uint32_t id;
	uint64_t token;
} rawc;

static int rawc_send(rawc *r, uint16_t code, uint8_t flags, uint64_t corr, const void *p,
		     size_t len)
{
	uint8_t buf[1024];
	mbx_hdr h = { .magic = MBX_MAGIC,
		      .version = MBX_VERSION,
		      .kind = MBX_KIND_COMMAND,
		      .code = code,
		      .line = LINE,
		      .flags = flags,
		      .client = r->id,
		      .token = r->token,
		      .corr = corr };
	int n = mbx_msg_build(buf, sizeof buf, &h, p, len);

	if (n < 0)
		return n;
	for (unsigned i = 0; i < 400; i++) { /* a full queue: wait, 2 s */
		if (mq_send(r->cmd, (const char *)buf, (size_t)n, 0) == 0)
			return 0;
		if (errno != EAGAIN)
			return -errno;
		sleep_ms(5);
	}
	return -EAGAIN;
}

/* The next response (2 s at most): 0 and *h, or -ETIMEDOUT. */
static int rawc_recv(rawc *r, mbx_hdr *h, void *p, size_t cap)
{
	uint8_t buf[1024];
	struct pollfd pf = { .fd = (int)r->resp, .events = POLLIN };

	if (poll(&pf, 1, 2000) != 1)
		return -ETIMEDOUT;
	ssize_t n = mq_receive(r->resp, (char *)buf, sizeof buf, NULL);

	if (n < 0 || mbx_hdr_decode(buf, (size_t)n, h, NULL) < 0)
		return -EIO;
	if (p)
		memcpy(p, buf + MBX_HDR_SIZE, h->len < cap ? h->len : cap);
	return 0;
}

static void rawc_names(rawc *r, unsigned n)
{
	snprintf(r->rn, sizeof r->rn, "/%s.n%u.resp", instance, n);
	snprintf(r->en, sizeof r->en, "/%s.n%u.evt", instance, n);
}

/* Create queues n (depth 2: a chunk window of one), not registered yet. */
static int rawc_create(rawc *r, unsigned n)
{
	struct mq_attr a = { .mq_maxmsg = 2, .mq_msgsize = 1024 };

	rawc_names(r, n);
	mq_unlink(r->rn);
	mq_unlink(r->en);
	r->resp = mq_open(r->rn, O_CREAT | O_EXCL | O_RDONLY | O_NONBLOCK, 0600, &a);
	r->evt = mq_open(r->en, O_CREAT | O_EXCL | O_RDONLY | O_NONBLOCK, 0600, &a);
	r->cmd = mq_open(qname, O_WRONLY | O_NONBLOCK);
	if (r->resp == (mqd_t)-1 || r->evt == (mqd_t)-1 || r->cmd == (mqd_t)-1)
		return -errno;
	return 0;
}

/* Register created queues; returns the status of the answer. */
static int rawc_register_created(rawc *r)
{
	mbx_register_req rq;
	mbx_register_resp rs;
	mbx_hdr h;

	memset(&rq, 0, sizeof rq);
	rq.pid = (uint32_t)getpid();
	rq.uid = (uint32_t)geteuid();
	strcpy(rq.resp_queue, r->rn);
	strcpy(rq.event_queue, r->en);
	r->id = 0;
	r->token = 0;
	if (rawc_send(r, MBX_CMD_REGISTER, 0, 1, &rq, sizeof rq) < 0 ||
	    rawc_recv(r, &h, &rs, sizeof rs) < 0)
		return -ETIMEDOUT;
	if (h.status == 0) {
		r->id = rs.client;
		r->token = rs.token;
		rawc_send(r, MBX_CMD_PING, MBX_F_NO_REPLY, 2, NULL, 0); /* confirm */
	}
	return h.status;
}

static int rawc_register(rawc *r, unsigned n)
{
	int rc = rawc_create(r, n);

	return rc ? rc : rawc_register_created(r);
}

static void rawc_close(rawc *r)
{
	mq_close(r->cmd);
	mq_close(r->resp);
	mq_close(r->evt);
	mq_unlink(r->rn);
	mq_unlink(r->en);
}

/* uid 65534 with queues of its own: a REGISTER naming as its sender a
 * live process of another user (the test, root) is refused unanswered;
 * the same REGISTER naming its own pid is registered. The daemon tells the
 * two apart only by the Uid: line of /proc/PID/status (docs/mailbox.md,
 * "Security model"). */
static int child_register_naming_pids(void *arg)
{
	rawc r;
	mbx_register_req rq = { .pid = (uint32_t)getppid(), .uid = NOBODY };

	(void)arg;
	CHECK(become_nobody() == 0);
	CHECK(rawc_create(&r, 40) == 0); /* a pair no other test uses */
	strcpy(rq.resp_queue, r.rn);
	strcpy(rq.event_queue, r.en);
	CHECK(rawc_send(&r, MBX_CMD_REGISTER, 0, 1, &rq, sizeof rq) == 0);
	/* FIFO: the answer read here is the second REGISTER's */
	CHECK(rawc_register_created(&r) == 0);
	rawc_close(&r);
	return 0;
}

static void test_register_naming_another_users_process_is_refused(void)
{
	mbx_server_config cfg = base_cfg();

	start(&cfg);
	mbx_server_stats before = stats();
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_register_naming_pids, NULL)),
				      "the REGISTER naming its own pid was not registered");
	mbx_server_stats after = stats();
	TEST_ASSERT_EQUAL_UINT64(before.reg_refused + 1, after.reg_refused);
	TEST_ASSERT_EQUAL_UINT64(before.access_denied + 1, after.access_denied);
	TEST_ASSERT_EQUAL_UINT64(before.clients_registered + 1, after.clients_registered);
}

/* The read-only user (65534) takes all it can: registrations, parked
 * requests, transfer slots it never acknowledges, an endless timeout. */
static int child_greedy_reader(void *arg)
{
	sync2 *s = arg;
	rawc r[8];
	unsigned ok = 0;
	mbx_hdr h;

	CHECK(become_nobody() == 0);
	for (unsigned i = 0; i < 8; i++) {
		int st = rawc_register(&r[i], i);

		CHECK(st == 0 || st == MBX_E_FULL);
		if (st == 0)
			ok++;
		else
			break;
	}
	fprintf(stderr, "reader: %u registrations\n", ok);
	CHECK(ok >= 1);
	/* an SDO request that would hold a channel for ever (asked first: its
	 * answer must find room in the small response queue) */
	mbx_sdo_req sdo = { .node = 5, .index = 0x1018, .sub = 1, .timeout_ms = 0xFFFFFFFFu };
	int got_param = 0;

	CHECK(rawc_send(&r[0], MBX_CMD_SDO_UPLOAD, 0, 300, &sdo, sizeof sdo) == 0);
	if (rawc_recv(&r[0], &h, NULL, 0) == 0 && h.corr == 300)
		got_param = h.status == MBX_E_PARAM;
	if (!got_param)
		fprintf(stderr, "reader: the endless SDO timeout was accepted\n");
	/* parked requests: as many as it likes */
	mbx_obj_req hold = { .index = 0x2002 };

	for (unsigned i = 0; i < 20; i++)
		CHECK(rawc_send(&r[0], MBX_CMD_OD_READ, MBX_F_NO_REPLY, 100 + i, &hold,
				sizeof hold) == 0);
	/* big answers it never acknowledges, from every client it has */
	mbx_obj_req big = { .index = 0x2001 };

	for (unsigned i = 0; i < ok; i++)
		for (unsigned k = 0; k < 2; k++)
			CHECK(rawc_send(&r[i], MBX_CMD_OD_READ, 0, 200 + k, &big, sizeof big) == 0);
	child_ready(s);
	child_wait_go(s);
	for (unsigned i = 0; i < ok; i++)
		rawc_close(&r[i]);
	return got_param ? 0 : 3;
}

/* A writer (root, libcogw) that must be served despite the reader. */
static int child_writer(void *arg)
{
	cogw *h;
	uint8_t v[5000] = { 7 };
	uint32_t abort = 0;
	int rc;

	(void)arg;
	CHECK(cogw_open(&h, instance) == 0);
	rc = cogw_ping(h, LINE, 3000);
	if (rc)
		fprintf(stderr, "writer: register: %s\n", cogw_strerror(rc));
	CHECK(rc == 0);
	rc = cogw_od_write(h, LINE, 0x2001, 0, v, 4, 3000, &abort);
	if (rc)
		fprintf(stderr, "writer: small write: %s\n", cogw_strerror(rc));
	CHECK(rc == 0);
	rc = cogw_od_write(h, LINE, 0x2001, 0, v, sizeof v, 3000, &abort);
	if (rc)
		fprintf(stderr, "writer: chunked write: %s\n", cogw_strerror(rc));
	CHECK(rc == 0);
	cogw_close(h);
	return 0;
}

static void test_a_reader_cannot_starve_a_writer(void)
{
	mbx_access_rule rules[] = { { .uid = NOBODY, .access = MBX_ACCESS_READ } };
	mbx_server_config cfg = base_cfg();
	sync2 s;
	pid_t reader;

	cfg.rules = rules;
	cfg.n_rules = 1;
	cfg.register_timeout_ms = 10000;
	cfg.xfer_slots = 2;
	cfg.max_transfer = 64 * 1024;
	cfg.read_outstanding = HELD_MAX / 2;
	start(&cfg);
	sync_init(&s);
	reader = spawn(child_greedy_reader, &s);
	parent_wait_ready(&s);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_writer, NULL)),
				      "the writer was refused (FULL/BUSY)");
	TEST_ASSERT_EQUAL_UINT(2, fl.writes_ok);
	TEST_ASSERT_TRUE(stats().limited > 0);
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(reader),
				      "a request timeout above the ceiling was accepted");
}

/* ---- 5 and 9: a transfer never acknowledged, the transfer memory budget ------- */

/* uid 65534 (read-only): a big answer it never acknowledges, and a second
 * one (another registration) that the budget must refuse. */
static int child_budget_reader(void *arg)
{
	sync2 *s = arg;
	rawc r[2];
	mbx_hdr h;
	mbx_obj_req big = { .index = 0x2001 };

	CHECK(become_nobody() == 0);
	CHECK(rawc_register(&r[0], 0) == 0 && rawc_register(&r[1], 1) == 0);
	CHECK(rawc_send(&r[0], MBX_CMD_OD_READ, 0, 10, &big, sizeof big) == 0);
	CHECK(rawc_recv(&r[0], &h, NULL, 0) == 0 && (h.flags & MBX_F_CHUNKED));
	CHECK(rawc_send(&r[1], MBX_CMD_OD_READ, 0, 11, &big, sizeof big) == 0);
	CHECK(rawc_recv(&r[1], &h, NULL, 0) == 0);
	if (h.status != MBX_E_NO_MEMORY)
		fprintf(stderr, "budget reader: %s\n", mbx_status_to_string(h.status));
	CHECK(h.status == MBX_E_NO_MEMORY);
	child_ready(s);
	child_wait_go(s);
	rawc_close(&r[0]);
	rawc_close(&r[1]);
	return 0;
}

static int child_big_reader(void *arg)
{
	cogw *h;
	uint8_t v[BIG_ANSWER];
	size_t len = 0;
	uint32_t abort = 0;
	int rc;

	(void)arg;
	CHECK(cogw_open(&h, instance) == 0);
	rc = cogw_od_read(h, LINE, 0x2001, 0, v, sizeof v, &len, 3000, &abort);
	if (rc)
		fprintf(stderr, "big reader: %s\n", cogw_strerror(rc));
	CHECK(rc == 0 && len == sizeof v);
	cogw_close(h);
	return 0;
}

static void test_an_unacknowledged_transfer_and_the_memory_budget(void)
{
	mbx_access_rule rules[] = { { .uid = NOBODY, .access = MBX_ACCESS_READ } };
	mbx_server_config cfg = base_cfg();
	mbx_budget budget;
	sync2 s;

	mbx_budget_init(&budget, 2 * BIG_ANSWER);
	cfg.rules = rules;
	cfg.n_rules = 1;
	cfg.register_timeout_ms = 10000;
	cfg.xfer_slots = 3;
	cfg.max_transfer = BIG_ANSWER;
	cfg.xfer_timeout_ms = 300;
	cfg.xfer_max_ms = 1000;
	cfg.budget = &budget;
	start(&cfg);
	sync_init(&s);
	pid_t reader = spawn(child_budget_reader, &s);
	parent_wait_ready(&s);
	/* readers leave max_transfer of the budget to writers */
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_big_reader, NULL)),
				      "the reader starved a writer of transfer memory");
	TEST_ASSERT_TRUE(stats().budget_refused >= 1);
	/* the never acknowledged answer loses its slot and its memory */
	for (unsigned i = 0; i < 500 && stats().xfer_expired == 0; i++)
		sleep_ms(10);
	TEST_ASSERT_EQUAL_UINT64(1, stats().xfer_expired);
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(&budget));
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(reader), "the budget did not refuse the reader");
	sync_close(&s);
}

/* ---- 6. registration cannot be turned against others ----------------------------- */

/* A root client (libcogw) and a client of 65534 (raw) that must register
 * and be served after an attack. */
static int child_nobody_registers(void *arg)
{
	rawc r;
	int st;

	(void)arg;
	CHECK(become_nobody() == 0);
	st = rawc_register(&r, 7);
	if (st)
		fprintf(stderr, "nobody: register: %s\n", mbx_status_to_string(st));
	CHECK(st == 0);
	rawc_close(&r);
	return 0;
}

/* Messages waiting in the queue behind name (-1: cannot tell). */
static long queue_waiting(const char *name)
{
	mqd_t q = mq_open(name, O_RDONLY | O_NONBLOCK);
	struct mq_attr a;
	long n = -1;

	if (q == (mqd_t)-1)
		return -1;
	if (mq_getattr(q, &a) == 0)
		n = a.mq_curmsgs;
	mq_close(q);
	return n;
}

/* Before: uid 65534 named the command queues of lines 0 and 3 (root,
 * 0620) with pid 1; each REGISTER made a root client (root is exempt from
 * the per-user limit) until the table was full for everybody, and the
 * tokens went into the other lines' command queues. */
static void test_register_cannot_name_the_command_queues_of_any_line(void)
{
	mbx_server_config cfg = base_cfg(), other = base_cfg();
	char q0[MBX_QNAME_MAX], q3[MBX_QNAME_MAX];
	mbx_server *line0 = NULL, *line3 = NULL;
	attack a = { .times = 40, .uid = 0, .pid = 1 };

	start(&cfg);
	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(q0, sizeof q0, instance, 0));
	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(q3, sizeof q3, instance, 3));
	other.queue_mode = 0620;
	other.line = 0;
	other.queue_name = q0;
	TEST_ASSERT_EQUAL_INT(0, mbx_server_create(&line0, &other));
	other.line = 3;
	other.queue_name = q3;
	TEST_ASSERT_EQUAL_INT(0, mbx_server_create(&line3, &other));
	memcpy(a.resp, q3, sizeof a.resp);
	memcpy(a.evt, q0, sizeof a.evt);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	sleep_ms(300);
	mbx_server_stats st = stats();
	long w0 = queue_waiting(q0), w3 = queue_waiting(q3);

	printf("other lines' command queues: %u REGISTERs, %" PRIu64 " clients registered, "
	       "%ld + %ld messages written into them\n",
	       a.times, st.clients_registered, w3, w0);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(0, st.clients_registered, "the attack registered clients");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, w3 + w0, "written into another line's command queue");
	TEST_ASSERT_EQUAL_UINT64(a.times, st.reg_refused);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_writer, NULL)), "root was locked out");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_nobody_registers, NULL)),
				      "65534 was locked out");
	mbx_server_destroy(line0);
	mbx_server_destroy(line3);
	mq_unlink(q0);
	mq_unlink(q3);
}

/* uid 1000 with a per-user limit of 2: one registration used, the queues
 * of a second made but not registered yet; during the attack it waits.
 * Its queues are numbered apart from those other tests leave behind. */
#define QUOTA_PAIRS 20
static int child_quota_victim(void *arg)
{
	sync2 *s = arg;
	rawc r[3];
	int st;

	CHECK(become(VICTIM_UID) == 0);
	CHECK(rawc_register(&r[0], QUOTA_PAIRS) == 0);
	CHECK(rawc_create(&r[1], QUOTA_PAIRS + 1) == 0);
	child_ready(s);
	child_wait_go(s);
	st = rawc_register_created(&r[1]);
	if (st)
		fprintf(stderr, "victim: second registration: %s\n", mbx_status_to_string(st));
	CHECK(st == 0);
	/* the limit itself still holds */
	st = rawc_register(&r[2], QUOTA_PAIRS + 2);
	if (st != MBX_E_FULL)
		fprintf(stderr, "victim: third registration: %d\n", st);
	CHECK(st == MBX_E_FULL);
	for (unsigned i = 0; i < 3; i++)
		rawc_close(&r[i]);
	return 0;
}

/* Before: naming the victim's queues swapped (event queue as response
 * queue), mixed, or a pair it had not registered yet, with its pid, made
 * entries of uid 1000 until its quota was full: its own registration got
 * FULL for the attack's duration plus the registration window. */
static void test_register_cannot_fill_another_users_quota(void)
{
	mbx_server_config cfg = base_cfg();
	sync2 s;
	pid_t victim;
	rawc n0, n1;

	cfg.max_clients_per_uid = 2;
	cfg.register_timeout_ms = 10000;
	start(&cfg);
	sync_init(&s);
	victim = spawn(child_quota_victim, &s);
	parent_wait_ready(&s);
	rawc_names(&n0, QUOTA_PAIRS);
	rawc_names(&n1, QUOTA_PAIRS + 1);
	const char *const named[][2] = {
		{ n0.en, n0.rn }, /* swapped */
		{ n1.en, n1.rn }, /* swapped, the pair not registered yet */
		{ n0.rn, n1.en }, /* mixed */
		{ n1.rn, n1.en }, /* the pair not registered yet */
		{ n0.rn, n0.en }, /* the pair in use */
	};
	for (size_t i = 0; i < sizeof named / sizeof named[0]; i++) {
		attack a = { .times = 5, .uid = VICTIM_UID, .pid = (uint32_t)victim };

		snprintf(a.resp, sizeof a.resp, "%s", named[i][0]);
		snprintf(a.evt, sizeof a.evt, "%s", named[i][1]);
		TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	}
	sleep_ms(300);
	printf("another user's quota: 25 REGISTERs, %u entries of uid %u (limit 2)\n",
	       stats().clients, VICTIM_UID);
	TEST_ASSERT_TRUE_MESSAGE(stats().clients <= 2, "the attack took the victim's quota");
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(victim), "the victim was refused");
	sync_close(&s);
}

/* Shared (mmap) between the parent and the flood test's victim. */
typedef struct flood_shared {
	sync2 s;
	unsigned calls, failed;
	uint64_t slowest_us;
	cogw_stats lib;
} flood_shared;

#define FLOOD_MS 3000

/* uid 1000 (libcogw): SDO uploads one after the other while the flood
 * runs; the slowest call is the figure. */
static int child_flood_victim(void *arg)
{
	flood_shared *rep = arg;
	sync2 *s = &rep->s;
	cogw *h;
	uint8_t v[8];
	size_t len;
	uint32_t abort;

	CHECK(become(VICTIM_UID) == 0);
	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s);
	for (uint64_t end = now_us() + FLOOD_MS * 1000u; now_us() < end;) {
		uint64_t t0 = now_us();
		int rc = cogw_sdo_read(h, LINE, 5, 0x1018, 1, v, sizeof v, &len, CALL_MS, &abort);
		uint64_t took = now_us() - t0;

		rep->calls++;
		if (rc)
			rep->failed++;
		if (took > rep->slowest_us)
			rep->slowest_us = took;
	}
	cogw_get_stats(h, &rep->lib);
	cogw_close(h);
	return 0;
}

/* 65534: REGISTERs naming the victim's queues, as fast as the command
 * queue takes them, for FLOOD_MS: claims that do not match (root's uid, a
 * dead pid), or (as_owner) the owner's uid and the victim's pid. */
static int child_register_flood(void *arg)
{
	const attack *a = arg;
	unsigned sent = 0;
	mqd_t cmd;

	CHECK(become_nobody() == 0);
	cmd = mq_open(qname, O_WRONLY);
	CHECK(cmd != (mqd_t)-1);
	for (uint64_t end = now_us() + FLOOD_MS * 1000u; now_us() < end; sent++)
		CHECK(send_register(cmd, a, sent, sent % 2 && !a->as_owner ? 0 : a->uid,
				    sent % 2 || a->as_owner ? a->pid : dead_pid()) == 0);
	mq_close(cmd);
	printf("flood: %u REGISTERs in %u ms\n", sent, FLOOD_MS);
	fflush(stdout);
	return 0;
}

/* Before: every refusal went to the response queue the REGISTER named:
 * the victim's queue filled with answers nobody asked for, its own
 * answers were dropped and its calls timed out. */
static void test_register_refusals_are_no_weapon(void)
{
	mbx_server_config cfg = base_cfg();
	flood_shared *sh = mmap(NULL, sizeof *sh, PROT_READ | PROT_WRITE,
				MAP_SHARED | MAP_ANONYMOUS, -1, 0);
	attack a = { .uid = VICTIM_UID };
	mbx_client_info ci;
	pid_t victim, flood;

	TEST_ASSERT_TRUE(sh != MAP_FAILED);
	memset(sh, 0, sizeof *sh);
	start(&cfg);
	sync_init(&sh->s);
	victim = spawn(child_flood_victim, sh);
	parent_wait_ready(&sh->s);
	ci = client_info(0);
	memcpy(a.resp, ci.resp_queue, sizeof a.resp);
	memcpy(a.evt, ci.event_queue, sizeof a.evt);
	a.pid = ci.pid;
	mbx_server_stats before = stats();

	flood = spawn(child_register_flood, &a);
	parent_go(&sh->s);
	TEST_ASSERT_EQUAL_INT(0, reap(flood));
	TEST_ASSERT_EQUAL_INT(0, reap(victim));
	mbx_server_stats st = stats();
	const flood_shared *r = sh;

	printf("refusal flood: %" PRIu64 " refused, %" PRIu64 " unanswered, %" PRIu64
	       " messages dropped; victim: %u calls, %u failed, slowest %.1f ms, %" PRIu64
	       " answers it never asked for\n",
	       st.reg_refused - before.reg_refused, st.reg_unanswered - before.reg_unanswered,
	       st.dropped - before.dropped, r->calls, r->failed, r->slowest_us / 1000.0,
	       r->lib.stray_responses);
	TEST_ASSERT_TRUE(st.reg_refused > before.reg_refused);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(0, r->lib.stray_responses,
					 "refusals were written to the victim's queue");
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(0, st.dropped - before.dropped, "messages were dropped");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, r->failed, "the victim's calls failed");
	TEST_ASSERT_TRUE(r->calls > 0);
	sync_close(&sh->s);
	munmap(sh, sizeof *sh);
}

/* uid 1000 (libcogw): registered; after the daemon restarted, its next
 * call must register again while somebody floods REGISTERs of its
 * queues. */
static int child_registers_during_flood(void *arg)
{
	sync2 *s = arg;
	cogw *h;
	uint8_t v[8];
	size_t len;
	uint32_t abort;
	int rc = COGW_E_RESTARTED;

	CHECK(become(VICTIM_UID) == 0);
	CHECK(cogw_open(&h, instance) == 0);
	CHECK(cogw_ping(h, LINE, CALL_MS) == 0);
	child_ready(s);
	child_wait_go(s);
	for (unsigned i = 0; i < 5 && (rc == COGW_E_RESTARTED || rc == COGW_E_NO_DAEMON); i++)
		rc = cogw_od_read(h, LINE, 0x2000, 0, v, sizeof v, &len, CALL_MS, &abort);
	if (rc)
		fprintf(stderr, "victim: after the restart: %s\n", cogw_strerror(rc));
	CHECK(rc == 0 && len == 4);
	cogw_close(h);
	return 0;
}

/* The victim's queues named with its uid and pid (as its own REGISTER
 * would) while it registers: before, each such REGISTER was one more
 * entry of uid 1000 until its quota was full and its own REGISTER got
 * FULL. Now the pair has one registration, answered again at most every
 * 100 ms under the flood's corr; libcogw takes such an answer as its own. */
static void test_a_flood_of_its_own_pair_does_not_stop_a_registration(void)
{
	mbx_server_config cfg = base_cfg();
	attack a = { .uid = VICTIM_UID, .as_owner = true };
	mbx_client_info ci;
	sync2 s;
	pid_t victim, flood;

	cfg.max_clients_per_uid = 2;
	cfg.register_timeout_ms = 10000; /* as the daemon's */
	start(&cfg);
	sync_init(&s);
	victim = spawn(child_registers_during_flood, &s);
	parent_wait_ready(&s);
	ci = client_info(0);
	memcpy(a.resp, ci.resp_queue, sizeof a.resp);
	memcpy(a.evt, ci.event_queue, sizeof a.evt);
	a.pid = ci.pid;
	stop(); /* a restarted daemon knows no client */
	start(&cfg);
	flood = spawn(child_register_flood, &a);
	sleep_ms(300);
	parent_go(&s);
	int rc = reap(victim);

	TEST_ASSERT_EQUAL_INT(0, reap(flood));
	printf("own pair flooded: %u registration%s of uid %u\n", stats().clients,
	       stats().clients == 1 ? "" : "s", VICTIM_UID);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "the victim could not register again");
	TEST_ASSERT_TRUE(stats().clients <= 1);
	sync_close(&s);
}

/* uid 1000, limit 2: three pairs made; the first two are registered by
 * somebody else (never confirmed), the third it registers itself. */
static int child_stale_victim(void *arg)
{
	sync2 *s = arg;
	rawc r[3];
	int st;

	CHECK(become(VICTIM_UID) == 0);
	for (unsigned i = 0; i < 3; i++)
		CHECK(rawc_create(&r[i], QUOTA_PAIRS + 5 + i) == 0);
	child_ready(s);
	child_wait_go(s);
	st = rawc_register_created(&r[2]);
	if (st)
		fprintf(stderr, "victim: own registration: %s\n", mbx_status_to_string(st));
	CHECK(st == 0);
	for (unsigned i = 0; i < 3; i++)
		rawc_close(&r[i]);
	return 0;
}

/* Pairs of a user registered by somebody else and never confirmed (the
 * user does not use them on this line) hold that user's quota for the
 * registration window, renewed by the next REGISTER. Past its confirm
 * grace (1 s), such a registration gives way to a new one. */
static void test_unconfirmed_registrations_give_way(void)
{
	mbx_server_config cfg = base_cfg();
	sync2 s;
	pid_t victim;

	cfg.max_clients_per_uid = 2;
	cfg.register_timeout_ms = 10000;
	start(&cfg);
	sync_init(&s);
	victim = spawn(child_stale_victim, &s);
	parent_wait_ready(&s);
	for (unsigned i = 0; i < 2; i++) {
		attack a = { .times = 1, .uid = VICTIM_UID, .pid = (uint32_t)victim };
		rawc n;

		rawc_names(&n, QUOTA_PAIRS + 5 + i);
		memcpy(a.resp, n.rn, sizeof a.resp);
		memcpy(a.evt, n.en, sizeof a.evt);
		TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	}
	sleep_ms(200);
	TEST_ASSERT_EQUAL_UINT32(2, stats().clients);
	sleep_ms(1000);
	parent_go(&s);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(victim), "the victim's quota stayed taken");
	sync_close(&s);
}

/* ---- 7. the daemon itself, under the unit's capabilities --------------------------- */

#define DAEMON_INSTANCE "secd"
#define DAEMON_LINE_JSON(n)                                                                \
	"{\"name\": \"line" #n "\", \"interface\": \"vcan" #n "\", \"bitrate\": 1000000, " \
	"\"node_id\": 127}"

static const char daemon_json[] =
	"{\"version\": 1, \"mailbox\": {\"instance\": \"" DAEMON_INSTANCE "\", "
	"\"queue_mode\": \"0622\", \"max_clients\": 8, \"default_access\": \"read\"}, "
	"\"lines\": [" DAEMON_LINE_JSON(0) ", " DAEMON_LINE_JSON(1) ", " DAEMON_LINE_JSON(2) "]}";

/* uid 1000 (libcogw): registers on every line and reads their counters. */
static int child_daemon_client(void *arg)
{
	const attack *a = arg;
	mbx_stats_wire ms[3];
	cogw *h;

	CHECK(become(VICTIM_UID) == 0);
	CHECK(cogw_open(&h, DAEMON_INSTANCE) == 0);
	for (unsigned l = 0; l < 3; l++) {
		int rc = cogw_mbx_stats(h, l, &ms[l], CALL_MS);

		if (rc)
			fprintf(stderr, "uid %u: line %u: %s\n", VICTIM_UID, l, cogw_strerror(rc));
		CHECK(rc == 0);
	}
	printf("cogwd, line 1: %u REGISTERs naming the command queues of lines 2 and 0 "
	       "with pid 1: %u client on line 1 (uid %u), %" PRIu64 " refused; malformed "
	       "messages on line 0: %" PRIu64 ", line 2: %" PRIu64 "\n",
	       a->times, ms[1].clients, VICTIM_UID, ms[1].reg_refused, ms[0].malformed,
	       ms[2].malformed);
	fflush(stdout);
	CHECK(ms[1].clients == 1);
	CHECK(ms[1].reg_refused == a->times);
	CHECK(ms[0].malformed == 0 && ms[2].malformed == 0);
	cogw_close(h);
	return 0;
}

/* The attack of test_register_cannot_name_the_command_queues_of_any_line
 * against cogwd itself with three lines, run with exactly the capability
 * bounding set of etc/cogwd.service: 65534 names the command queues of
 * lines 2 and 0 in REGISTERs to line 1; uid 1000 and root must still
 * register there, and nothing may reach lines 0 and 2. */
static void test_the_daemon_keeps_its_lines_open(void)
{
	static daemon_run d;
	char bset[512], q[3][MBX_QNAME_MAX];
	attack a = { .times = 40, .uid = 0, .pid = 1, .line = 1 };
	cogw *h;

	if (access("/sys/class/net/vcan2", F_OK) != 0)
		TEST_IGNORE_MESSAGE("needs vcan0..2 (tests/vcan/run -n 3)");
	if (access("/usr/bin/setpriv", X_OK) != 0)
		TEST_IGNORE_MESSAGE("setpriv not installed");
	TEST_ASSERT_EQUAL_INT(0, daemon_unit_bounding_set(bset, sizeof bset));
	const char *const wrapper[] = { "/usr/bin/setpriv", bset, NULL };
	int rc = daemon_start(&d, &(daemon_opts){ .config_json = daemon_json,
						  .instance = DAEMON_INSTANCE,
						  .n_lines = 3,
						  .notify = true,
						  .drop_notify = true,
						  .wrapper = wrapper });

	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "cogwd did not come up under the unit's capabilities");
	for (unsigned l = 0; l < 3; l++)
		daemon_cmd_queue(&d, l, q[l], sizeof q[l]);
	a.cmd = q[1];
	snprintf(a.resp, sizeof a.resp, "%s", q[2]);
	snprintf(a.evt, sizeof a.evt, "%s", q[0]);
	TEST_ASSERT_EQUAL_INT(0, reap(spawn(child_register_as_nobody, &a)));
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, reap(spawn(child_daemon_client, &a)),
				      "uid 1000 was locked out, or the attack reached other lines");
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, DAEMON_INSTANCE));
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, cogw_ping(h, 1, CALL_MS), "root was locked out");
	cogw_close(h);
	daemon_cleanup(&d);
}

int main(void)
{
	pthread_mutex_init(&fl.mu, NULL);
	signal(SIGPIPE, SIG_IGN);
	UNITY_BEGIN();
	RUN_TEST(test_register_cannot_replace_a_live_client);
	RUN_TEST(test_register_with_dead_pid_unlinks_nothing);
	RUN_TEST(test_register_naming_another_users_process_is_refused);
	RUN_TEST(test_register_cannot_unlink_the_command_queue);
	RUN_TEST(test_dead_client_queues_are_still_removed);
	RUN_TEST(test_command_queue_is_write_only_for_clients);
	RUN_TEST(test_readable_command_queue_modes_are_refused);
	RUN_TEST(test_clients_survive_a_daemon_restart);
	RUN_TEST(test_a_reader_cannot_starve_a_writer);
	RUN_TEST(test_an_unacknowledged_transfer_and_the_memory_budget);
	RUN_TEST(test_register_cannot_name_the_command_queues_of_any_line);
	RUN_TEST(test_register_cannot_fill_another_users_quota);
	RUN_TEST(test_register_refusals_are_no_weapon);
	RUN_TEST(test_a_flood_of_its_own_pair_does_not_stop_a_registration);
	RUN_TEST(test_unconfirmed_registrations_give_way);
	RUN_TEST(test_the_daemon_keeps_its_lines_open);
	return UNITY_END();
}
