/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_internal.h - what libcogw's service files
 * (mailbox/client_api_*.c) use of its transport (mailbox/client*.c,
 * named in mailbox/client_transport.h). The service files only build a
 * request and read its answer; the handle, the lines' registrations and
 * the threads stay inside the transport, so calls go one way only:
 * service file -> transport. Not installed; hidden from
 * libcogw.so's exported symbols.
 */
#ifndef COGW_MAILBOX_CLIENT_INTERNAL_H
#define COGW_MAILBOX_CLIENT_INTERNAL_H

#include "mailbox/cogw.h"

#pragma GCC visibility push(hidden)

/* One blocking request on line and its answer: registers with the line on
 * first use (again, once, when the daemon restarted or reaped us), sends
 * fixed then data (chunked when they do not fit one message), and waits
 * until timeout_ms (0: the handle's default) for the answer, copied into
 * rbuf (at most rcap bytes; *rlen: the answer's whole length, and
 * COGW_E_TRUNCATED when it exceeds rcap). Returns 0 or a cogw_err; *abort:
 * the SDO abort code of a COGW_E_ABORT answer. */
int client_call(cogw *h, unsigned line, uint16_t code, const void *fixed, size_t flen,
		const void *data, size_t dlen, void *rbuf, size_t rcap, size_t *rlen,
		uint32_t *abort, unsigned timeout_ms);

/* A subscription the daemon accepted (filters: the request's whole table,
 * n_filters used), remembered to subscribe again after a re-registration;
 * starts the helper thread that does that. 0 or a cogw_err. */
int client_subscribed(cogw *h, unsigned line, uint32_t classes, uint8_t n_filters,
		      const mbx_raw_filter filters[MBX_RAW_FILTERS_MAX]);
/* An unsubscription the daemon accepted: no longer subscribed again. */
void client_unsubscribed(cogw *h, unsigned line, uint32_t classes);

#pragma GCC visibility pop

#endif
