/* SPDX-License-Identifier: MIT */
#include "apps/common/signal_loop.h"

#include <signal.h>
#include <stdio.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>

int signal_loop_open(const char *who, int *sigfd, int *epfd)
{
	sigset_t sigs;

	sigemptyset(&sigs);
	sigaddset(&sigs, SIGTERM);
	sigaddset(&sigs, SIGINT);
	sigaddset(&sigs, SIGHUP);
	sigprocmask(SIG_BLOCK, &sigs, NULL);
	signal(SIGPIPE, SIG_IGN);
	*sigfd = signalfd(-1, &sigs, SFD_NONBLOCK | SFD_CLOEXEC);
	*epfd = epoll_create1(EPOLL_CLOEXEC);
	if (*sigfd < 0 || *epfd < 0) {
		perror(who);
		return -1;
	}
	return 0;
}
