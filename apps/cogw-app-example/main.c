/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-app-example/main.c - an application on the mailbox
 * (docs/application.md walks through it): it owns three objects of a
 * line's own node and keeps them up to date.
 *
 *   base+0 UNSIGNED32 rw, served: a set-point. Reads get the value kept
 *          here; writes above --limit are refused with 06090031h (value
 *          too high) and change nothing.
 *   base+1 VISIBLE_STRING ro, served: a status text made at every read.
 *   base+2 UNSIGNED16 rw, held, TPDO-mappable: a counter counted up every
 *          --period-ms and written with a TPDO trigger; with --tpdo N
 *          --cob ID the program maps it into the daemon's TPDO N itself
 *          (CiA 301 §7.5.2.37 order: invalidate, clear the mapping, map,
 *          count, validate), else the configuration maps it.
 *
 * One event loop (epoll): the signals, libcogw's event descriptor (the
 * indications) and a timerfd for the counter. Every indication is
 * answered at once: a served object must answer within the line's SDO
 * timeout, or the requester gets 08000020h.
 *
 * Exit status: 0 on SIGTERM/SIGINT, 1 on a failure at run time, 2 for a
 * bad command line, 3 when the objects cannot be claimed (taken, a bound,
 * or no daemon).
 */
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include "apps/common/signal_loop.h"
#include "apps/common/version.h"
#include "mailbox/cogw.h"

#define AB_VALUE_HIGH 0x06090031u /* CiA 301: value of parameter written too high */

struct app {
	cogw *h;
	unsigned line;
	uint16_t base;
	uint32_t limit;
	unsigned period_ms;
	unsigned tpdo; /* 0 = the configuration maps the counter */
	uint32_t cob;
	const char *instance;
	/* the values */
	uint32_t setpoint;
	uint16_t counter;
	unsigned reads, writes, refused;
};

static int usage(FILE *f, int rc)
{
	fprintf(f, "usage: cogw-app-example [options]\n"
		   "  -I, --instance NAME   daemon instance (default main)\n"
		   "  -l, --line N          line (default 0)\n"
		   "  -b, --base INDEX      first of the three objects (default 0x2200;\n"
		   "                        2000h..5FFDh or 6000h..9FFDh)\n"
		   "  -L, --limit N         largest set-point accepted (default 1000)\n"
		   "  -p, --period-ms N     counter period (default 100, 0 = never)\n"
		   "  -t, --tpdo N          map the counter into the daemon's TPDO N (1..512)\n"
		   "  -c, --cob ID          its COB-ID (with --tpdo)\n"
		   "      --version\n");
	return rc;
}

static bool parse_u32(const char *s, uint32_t min, uint32_t max, uint32_t *out)
{
	char *end;
	errno = 0;
	unsigned long v = strtoul(s, &end, 0);
	if (errno || end == s || *end || v < min || v > max || s[0] == '-')
		return false;
	*out = (uint32_t)v;
	return true;
}

/* The numeric options: their letter, range and where they go. */
struct num_opt {
	int letter;
	uint32_t min, max;
	uint32_t *dst;
};

static const struct num_opt *num_opt_of(const struct num_opt *t, size_t n, int letter)
{
	for (size_t i = 0; i < n; i++)
		if (t[i].letter == letter)
			return &t[i];
	return NULL;
}

static int parse_args(struct app *a, int argc, char **argv)
{
	static const struct option opts[] = {
		{ "instance", 1, 0, 'I' }, { "line", 1, 0, 'l' },      { "base", 1, 0, 'b' },
		{ "limit", 1, 0, 'L' },    { "period-ms", 1, 0, 'p' }, { "tpdo", 1, 0, 't' },
		{ "cob", 1, 0, 'c' },      { "help", 0, 0, 'h' },      { 0, 0, 0, 0 }
	};
	uint32_t line = 0, base = 0x2200, period = 100, tpdo = 0;
	const struct num_opt nums[] = {
		{ 'l', 0, MBX_LINES_MAX - 1, &line },
		{ 'b', 0x2000, 0x9FFD, &base },
		{ 'L', 0, UINT32_MAX, &a->limit },
		{ 'p', 0, 3600000, &period },
		{ 't', 1, 512, &tpdo },
		{ 'c', 1, 0x7FF, &a->cob },
	};
	int c;
	while ((c = getopt_long(argc, argv, "I:l:b:L:p:t:c:h", opts, NULL)) != -1) {
		const struct num_opt *n = num_opt_of(nums, sizeof nums / sizeof nums[0], c);
		if (c == 'I')
			a->instance = optarg;
		else if (c == 'h')
			exit(usage(stdout, 0));
		else if (!n)
			return usage(stderr, 2);
		else if (!parse_u32(optarg, n->min, n->max, n->dst)) {
			fprintf(stderr, "cogw-app-example: bad value for -%c: %s\n", c, optarg);
			return 2;
		}
	}
	/* the three objects stay inside one of the two ranges */
	const char *bad = optind < argc                     ? "unexpected argument"
			  : base >= 0x5FFE && base < 0x6000 ? "--base: the objects must stay in "
							      "2000h..5FFFh or 6000h..9FFFh"
			  : tpdo && !a->cob                 ? "--tpdo needs --cob"
							    : NULL;
	if (bad) {
		fprintf(stderr, "cogw-app-example: %s\n", bad);
		return 2;
	}
	a->line = line;
	a->base = (uint16_t)base;
	a->period_ms = period;
	a->tpdo = tpdo;
	return 0;
}

/* ---- the objects ------------------------------------------------------------ */

static int claim_all(struct app *a)
{
	const mbx_app_claim_req objs[3] = {
		{ .index = a->base,
		  .kind = MBX_APP_SERVED,
		  .type = MBX_T_UNSIGNED32,
		  .access = MBX_APP_READ | MBX_APP_WRITE },
		{ .index = (uint16_t)(a->base + 1),
		  .kind = MBX_APP_SERVED,
		  .type = MBX_T_VISIBLE_STRING,
		  .access = MBX_APP_READ,
		  .max_size = 64 },
		{ .index = (uint16_t)(a->base + 2),
		  .kind = MBX_APP_HELD,
		  .type = MBX_T_UNSIGNED16,
		  .access = MBX_APP_READ | MBX_APP_WRITE | MBX_APP_TPDO },
	};
	for (int i = 0; i < 3; i++) {
		int rc = cogw_app_claim(a->h, a->line, &objs[i], NULL, 0, 0);
		if (rc < 0) {
			fprintf(stderr, "cogw-app-example: cannot own %04Xh: %s\n", objs[i].index,
				cogw_strerror(rc));
			return rc;
		}
	}
	return 0;
}

static int od_write_u32(struct app *a, uint16_t index, uint8_t sub, uint32_t v, size_t len)
{
	uint32_t abort = 0;
	int rc = cogw_od_write(a->h, a->line, index, sub, &v, len, 0, &abort);
	if (rc < 0)
		fprintf(stderr, "cogw-app-example: %04Xh:%u: %s (abort %08X)\n", index, sub,
			cogw_strerror(rc), abort);
	return rc;
}

/* The counter into TPDO n, in the order CiA 301 asks for: the PDO
 * invalid while its mapping changes. */
static int map_counter(struct app *a)
{
	uint16_t comm = (uint16_t)(0x1800 + a->tpdo - 1), map = (uint16_t)(0x1A00 + a->tpdo - 1);
	uint32_t entry = (uint32_t)(a->base + 2) << 16 | 0x10;
	int rc;
	if ((rc = od_write_u32(a, comm, 1, 0x80000000u | a->cob, 4)) < 0 ||
	    (rc = od_write_u32(a, map, 0, 0, 1)) < 0 ||
	    (rc = od_write_u32(a, map, 1, entry, 4)) < 0 ||
	    (rc = od_write_u32(a, map, 0, 1, 1)) < 0 || (rc = od_write_u32(a, comm, 2, 254, 1)) < 0)
		return rc;
	return od_write_u32(a, comm, 1, a->cob, 4);
}

static void count(struct app *a)
{
	a->counter++;
	int rc = cogw_pdo_write(a->h, a->line, (uint16_t)(a->base + 2), 0, &a->counter, 2, 1, 0);
	if (rc < 0)
		fprintf(stderr, "cogw-app-example: counter: %s\n", cogw_strerror(rc));
}

/* ---- the indications ---------------------------------------------------------- */

static void answer_read(struct app *a, const mbx_ev_app_ind *ind)
{
	char text[64];
	if (ind->index == a->base)
		cogw_app_answer(a->h, a->line, ind->ind, 0, &a->setpoint, 4, 0);
	else {
		int n = snprintf(text, sizeof text, "running: %u reads, %u writes, %u refused",
				 a->reads, a->writes, a->refused);
		cogw_app_answer(a->h, a->line, ind->ind, 0, text, (size_t)n, 0);
	}
}

static void on_indication(struct app *a, const cogw_msg *m)
{
	mbx_ev_app_ind ind;
	const uint8_t *data;
	if (cogw_app_ind_parse(m->data, m->len, &ind, &data) < 0)
		return;
	if (ind.op == MBX_APP_OP_READ) {
		a->reads++;
		return answer_read(a, &ind);
	}
	a->writes++;
	uint32_t v;
	if (ind.index != a->base || ind.size != 4) /* the status text is ro */
		return (void)cogw_app_answer(a->h, a->line, ind.ind, 0x06010002u, NULL, 0, 0);
	memcpy(&v, data, 4);
	if (v > a->limit) {
		a->refused++;
		cogw_app_answer(a->h, a->line, ind.ind, AB_VALUE_HIGH, NULL, 0, 0);
		return;
	}
	a->setpoint = v;
	cogw_app_answer(a->h, a->line, ind.ind, 0, NULL, 0, 0);
	printf("set-point %u\n", v);
	fflush(stdout);
}

static void on_event(struct app *a, const cogw_msg *m)
{
	mbx_ev_app_written w;
	const uint8_t *data;
	if (m->code == MBX_EV_APP_IND)
		on_indication(a, m);
	else if (m->code == MBX_EV_APP_WRITTEN &&
		 cogw_app_written_parse(m->data, m->len, &w, &data) == 0 && w.inline_len == 2) {
		memcpy(&a->counter, data, 2); /* someone set the counter: count on from there */
		printf("counter set to %u from outside\n", a->counter);
		fflush(stdout);
	}
}

/* ---- the loop --------------------------------------------------------------------- */

static int arm_period(unsigned period_ms)
{
	int fd = timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK);
	if (fd < 0 || !period_ms)
		return fd;
	struct itimerspec its = { .it_interval = { period_ms / 1000,
						   (long)(period_ms % 1000) * 1000000 } };
	its.it_value = its.it_interval;
	timerfd_settime(fd, 0, &its, NULL);
	return fd;
}

static int run(struct app *a, int sigfd, int epfd)
{
	int tfd = arm_period(a->period_ms), evfd = cogw_event_fd(a->h);
	struct epoll_event ev = { .events = EPOLLIN };
	if (tfd < 0 || evfd < 0)
		return 1;
	ev.data.fd = sigfd;
	epoll_ctl(epfd, EPOLL_CTL_ADD, sigfd, &ev);
	ev.data.fd = tfd;
	epoll_ctl(epfd, EPOLL_CTL_ADD, tfd, &ev);
	ev.data.fd = evfd;
	epoll_ctl(epfd, EPOLL_CTL_ADD, evfd, &ev);
	for (;;) {
		struct epoll_event evs[4];
		int n = epoll_wait(epfd, evs, 4, -1);
		for (int i = 0; i < n; i++) {
			struct signalfd_siginfo si;
			if (evs[i].data.fd == sigfd) {
				if (read(sigfd, &si, sizeof si) == sizeof si &&
				    si.ssi_signo == SIGHUP)
					continue; /* nothing to reload */
				close(tfd);
				return 0;
			}
			if (evs[i].data.fd == tfd) {
				uint64_t ticks;
				if (read(tfd, &ticks, sizeof ticks) == sizeof ticks)
					count(a);
				continue;
			}
			cogw_msg m;
			while (cogw_recv(a->h, &m, 0) == 0) {
				if (m.kind == MBX_KIND_EVENT)
					on_event(a, &m);
				cogw_msg_release(&m);
			}
		}
	}
}

int main(int argc, char **argv)
{
	struct app a = { .instance = "main", .base = 0x2200, .limit = 1000, .period_ms = 100 };
	int sigfd, epfd, rc;
	if (cogw_version_asked("cogw-app-example", argc, argv))
		return 0;
	if ((rc = parse_args(&a, argc, argv)))
		return rc;
	if (signal_loop_open("cogw-app-example", &sigfd, &epfd) < 0)
		return 1;
	if ((rc = cogw_open(&a.h, a.instance)) < 0) {
		fprintf(stderr, "cogw-app-example: %s: %s\n", a.instance, cogw_strerror(rc));
		return 1;
	}
	if (claim_all(&a) < 0 || (a.tpdo && map_counter(&a) < 0)) {
		cogw_close(a.h);
		return 3;
	}
	printf("cogw-app-example: line %u, objects %04Xh..%04Xh\n", a.line, a.base, a.base + 2);
	fflush(stdout);
	rc = run(&a, sigfd, epfd);
	cogw_close(a.h); /* the objects have no owner from here on */
	return rc;
}
