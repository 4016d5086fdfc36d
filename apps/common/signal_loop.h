/* SPDX-License-Identifier: MIT */
/*
 * apps/common/signal_loop.h - the start of a mailbox client's event loop
 * (cogw-ascii, cogw-mqtt): SIGTERM, SIGINT and SIGHUP blocked and delivered
 * through a signalfd, SIGPIPE ignored (a peer that went away is an error of
 * its write, not the end of the process), an epoll set.
 */
#ifndef COGW_APPS_COMMON_SIGNAL_LOOP_H
#define COGW_APPS_COMMON_SIGNAL_LOOP_H

/* Call it before cogw_open(): libcogw's helper thread must inherit the
 * blocked signals, or a SIGTERM would end the process there. 0, or -1
 * with "who: reason" on stderr. */
int signal_loop_open(const char *who, int *sigfd, int *epfd);

#endif /* COGW_APPS_COMMON_SIGNAL_LOOP_H */
