/* SPDX-License-Identifier: MIT */
/*
 * mailbox/cogw_scan.h - libcogw: the node scan of a line and its cache
 * (docs/mailbox.md "Node scan and unknown nodes"). Same rules as
 * mailbox/cogw.h: a handle from cogw_open(), any thread that owns the
 * handle, returns 0 or a negative cogw_err.
 */
#ifndef COGW_MAILBOX_COGW_SCAN_H
#define COGW_MAILBOX_COGW_SCAN_H

#include "mailbox/cogw.h"

/* A scan's figures and the nodes found (by node-ID). */
typedef struct cogw_scan_result {
	mbx_scan_resp figures;
	mbx_node_ident nodes[127];
	unsigned n_nodes;
} cogw_scan_result;

/*
 * Ask node-IDs first..last of the line (1 <= first <= last <= 127) for
 * 1000h and 1018h:1..4 and wait for the end of the scan. timeout_ms: per
 * SDO frame (0 = the line's default); parallel: nodes at once (0 = every
 * SDO client channel of the line); wait_ms: how long to wait for the
 * answer (0 = cogw_scan_bound_ms() with one channel and at least 100 ms,
 * plus 5 s; the daemon caps it at mailbox.max_request_timeout_ms).
 * COGW_E_BUSY while
 * another scan runs on that line; a write-type command (it keeps the
 * line's SDO client pool busy).
 */
int cogw_node_scan(cogw *h, unsigned line, uint8_t first, uint8_t last, unsigned timeout_ms,
		   unsigned parallel, unsigned wait_ms, cogw_scan_result *out);
/* What the line read so far, by scans and from unknown nodes, and the last
 * scan's figures; answers at once. */
int cogw_node_scan_cache(cogw *h, unsigned line, cogw_scan_result *out);
/* The longest a scan of n node-IDs takes when no other transfer uses the
 * pool: ceil(n / parallel) x 5 reads x timeout_ms. */
unsigned cogw_scan_bound_ms(unsigned n, unsigned parallel, unsigned timeout_ms);

#endif /* COGW_MAILBOX_COGW_SCAN_H */
