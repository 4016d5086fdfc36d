/* SPDX-License-Identifier: MIT */
/*
 * probe_mq_wait CLIENT SERVER [CPU_CLIENT CPU_SERVER] - a raw POSIX mq
 * ping-pong between two processes, no libcogw: how the round trip depends
 * on the way each side waits for its queue. CLIENT and SERVER are each
 * "receive" (blocked in mq_receive), "poll" (poll() on the queue, then a
 * receive) or "epoll" (epoll_wait on an epoll set holding the queue, then a
 * receive: what the daemon's line thread and an event loop on
 * cogw_loop_fd() do). By hand, in the test VM (docs/fastpath.md "The
 * event-loop round trip in the VM"); prints p50 and p90, never a verdict.
 */
#include <fcntl.h>
#include <mqueue.h>
#include <poll.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/bench/support/bench.h"

#define WARM 100
#define SAMPLES 2000

static void pin(const char *cpu)
{
	cpu_set_t set;

	if (!cpu)
		return;
	CPU_ZERO(&set);
	CPU_SET(atoi(cpu), &set);
	sched_setaffinity(0, sizeof set, &set);
}

/* A message of q, waited for the way `how` says (epfd: q's epoll set). */
static void take(mqd_t q, const char *how, int epfd)
{
	struct pollfd pf = { .fd = (int)q, .events = POLLIN };
	struct epoll_event ev;
	char buf[64];

	if (strcmp(how, "poll") == 0)
		poll(&pf, 1, -1);
	else if (strcmp(how, "epoll") == 0)
		epoll_wait(epfd, &ev, 1, -1);
	mq_receive(q, buf, sizeof buf, NULL);
}

static int epoll_of(mqd_t q)
{
	struct epoll_event ev = { .events = EPOLLIN };
	int fd = epoll_create1(EPOLL_CLOEXEC);

	epoll_ctl(fd, EPOLL_CTL_ADD, (int)q, &ev);
	return fd;
}

int main(int argc, char **argv)
{
	struct mq_attr at = { .mq_maxmsg = 8, .mq_msgsize = 64 };
	static double rtt[SAMPLES];
	char ping_name[64], pong_name[64];

	if (argc != 3 && argc != 5) {
		fprintf(stderr, "usage: probe_mq_wait receive|poll|epoll receive|poll|epoll "
				"[CPU_CLIENT CPU_SERVER]\n");
		return 2;
	}
	snprintf(ping_name, sizeof ping_name, "/probe_mq_wait.%d.ping", (int)getpid());
	snprintf(pong_name, sizeof pong_name, "/probe_mq_wait.%d.pong", (int)getpid());
	mqd_t ping = mq_open(ping_name, O_RDWR | O_CREAT | O_EXCL, 0600, &at);
	mqd_t pong = mq_open(pong_name, O_RDWR | O_CREAT | O_EXCL, 0600, &at);

	mq_unlink(ping_name);
	mq_unlink(pong_name);
	if (ping == (mqd_t)-1 || pong == (mqd_t)-1) {
		perror("probe_mq_wait: mq_open");
		return 1;
	}
	if (fork() == 0) {
		int epfd = epoll_of(ping);

		pin(argc == 5 ? argv[4] : NULL);
		for (int i = 0; i < WARM + SAMPLES; i++) {
			take(ping, argv[2], epfd);
			mq_send(pong, "", 0, 0);
		}
		_exit(0);
	}
	int epfd = epoll_of(pong);

	pin(argc == 5 ? argv[3] : NULL);
	for (int i = 0; i < WARM + SAMPLES; i++) {
		uint64_t t0 = bench_now_ns();

		mq_send(ping, "", 0, 0);
		take(pong, argv[1], epfd);
		if (i >= WARM)
			rtt[i - WARM] = (double)(bench_now_ns() - t0) * 1e-3;
	}
	wait(NULL);
	double p90 = bench_percentile(rtt, SAMPLES, 90);

	printf("client %s, server %s%s%s%s%s: round trip p50 %.0f us, p90 %.0f us\n", argv[1],
	       argv[2], argc == 5 ? ", CPUs " : "", argc == 5 ? argv[3] : "", argc == 5 ? "/" : "",
	       argc == 5 ? argv[4] : "", bench_percentile(rtt, SAMPLES, 50), p90);
	return 0;
}
