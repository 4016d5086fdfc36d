/* SPDX-License-Identifier: MIT */
/*
 * apps/common/mbx_loop.h - how the front ends (cogw-ascii, cogw-mqtt) use
 * libcogw's loop handle (docs/mailbox.md "Event loops"): no helper thread,
 * the answers taken from the response queue in the wake-up of the front
 * end's own epoll loop, sends that never wait.
 */
#ifndef COGW_APPS_COMMON_MBX_LOOP_H
#define COGW_APPS_COMMON_MBX_LOOP_H

#include <stddef.h>
#include <stdint.h>

#include "mailbox/cogw.h"

/* A loop handle registered with lines 0..n_lines-1. A line whose
 * registration fails (the daemon is not running yet) is named on stderr
 * and registered at its first send. 0 or a cogw_err (the handle itself
 * could not be opened). */
int mbx_loop_open(cogw **h, const cogw_options *o, size_t n_lines, const char *who);

/* cogw_loop_send(), registering with the line first when it never was:
 * the one exchange that waits, bounded by attach_ms, once per line. */
int mbx_loop_send(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		  unsigned timeout_ms, uint64_t *corr);

/* The epoll_wait() time-out for a loop that wants to wake after want_ms
 * (-1: no wish of its own): the shorter of it and the handle's. */
int mbx_loop_wait_ms(cogw *h, int want_ms);

#endif /* COGW_APPS_COMMON_MBX_LOOP_H */
