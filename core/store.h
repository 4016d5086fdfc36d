/* SPDX-License-Identifier: MIT */
/*
 * core/store.h - store/restore parameters, 1010h/1011h (CiA 301 §7.5.2.13
 * and §7.5.2.14). The storage backend lives outside core: it is reached
 * through co_store_ops.
 *
 * - Sub 1 = all parameters, 2 = communication, 3 = application,
 *   4..7Fh = manufacturer specific. co_store_attach() creates the two
 *   arrays with n_subs sub-indexes if the OD lacks them, or hooks the ones
 *   the configuration created.
 * - Reads return the capability bits (bit 0: saves/restores on command,
 *   bit 1 (1010h only): saves autonomously).
 * - Writes must carry the signature "save" (65766173h) to 1010h or "load"
 *   (64616F6Ch) to 1011h; anything else gives 0x08000020. A correct write
 *   calls the backend op (whose abort code goes on the wire; it may return
 *   CO_OD_DEFERRED and answer later with sdo_server_continue()) and emits
 *   CO_EV_STORE / CO_EV_RESTORE. The stored value stays the capability.
 * - Without ops, a correct signature is accepted and only the event is
 *   emitted (the application then stores).
 */
#ifndef COGW_CORE_STORE_H
#define COGW_CORE_STORE_H

#include <stdint.h>

#include "core/co.h"

#define CO_STORE_SIG_SAVE 0x65766173u /* "save", bytes 73 61 76 65 */
#define CO_STORE_SIG_LOAD 0x64616F6Cu /* "load", bytes 6C 6F 61 64 */

#define CO_STORE_IDX_SAVE 0x1010u
#define CO_STORE_IDX_LOAD 0x1011u

#define CO_STORE_CAP_CMD 0x1u  /* on command */
#define CO_STORE_CAP_AUTO 0x2u /* autonomously (1010h only) */

typedef struct co_store_ops {
	/* Return 0, an abort code, or CO_OD_DEFERRED (SDO access only). */
	uint32_t (*save)(void *ctx, uint8_t sub, const co_od_access *a);
	uint32_t (*restore)(void *ctx, uint8_t sub, const co_od_access *a);
} co_store_ops;

extern const co_service co_svc_store;

/* n_subs 1..127. save_caps/restore_caps are the values reads return.
 * Returns 0, -EINVAL, -ENOMEM, -EEXIST if already attached. */
int co_store_attach(co_node *node, const co_store_ops *ops, void *ctx, uint8_t n_subs,
		    uint32_t save_caps, uint32_t restore_caps);

#endif /* COGW_CORE_STORE_H */
