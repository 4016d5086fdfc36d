/* SPDX-License-Identifier: MIT */
/*
 * mailbox/cogw_health.h - libcogw: the bus health of a line
 * (docs/mailbox.md "Bus health"). Same rules as mailbox/cogw.h: a handle
 * from cogw_open(), any thread that owns the handle, returns 0 or a
 * negative cogw_err.
 */
#ifndef COGW_MAILBOX_COGW_HEALTH_H
#define COGW_MAILBOX_COGW_HEALTH_H

#include "mailbox/cogw.h"

/* The controller state, the fault episodes and their counters. */
int cogw_line_health(cogw *h, unsigned line, mbx_line_health *out, unsigned timeout_ms);
/* Zero the counters (episodes, occurrences, restarts, drop counters;
 * running episodes go on). A write-type command: refused (COGW_E_ACCESS)
 * to clients with read rights only. */
int cogw_line_health_reset(cogw *h, unsigned line, unsigned timeout_ms);

#endif /* COGW_MAILBOX_COGW_HEALTH_H */
