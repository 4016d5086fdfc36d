/* SPDX-License-Identifier: MIT */
/*
 * core/errctrl.h - what heartbeat (core/heartbeat.c) and node/life guarding
 * (core/guarding.c) share, so that neither calls the other (CiA 301
 * §7.2.8.3.2: two error-control protocols, one error behaviour).
 *
 * - The error-control event (u.errctrl of core/event.h).
 * - The communication loss: EMCY 8130h (life guard / heartbeat error)
 *   then the 1029h:1 behaviour, and its end: 8130h is cleared once no
 *   source (heartbeat consumer, life guarding) reports a loss any more.
 * - Which remote nodes the guarding master polls: their 700h answers
 *   carry a toggle bit, so the heartbeat consumer leaves them to guarding.
 *
 * The service (co_svc_errctrl) runs before heartbeat and guarding in the
 * service table. All functions: owning thread only.
 */
#ifndef COGW_CORE_ERRCTRL_H
#define COGW_CORE_ERRCTRL_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

extern const co_service co_svc_errctrl;

/* Who reports a communication loss. */
typedef enum co_errctrl_source {
	CO_ERRCTRL_SRC_HEARTBEAT = 0, /* a 1016h consumer entry expired */
	CO_ERRCTRL_SRC_LIFE_GUARD,    /* our master stopped guarding us */
	CO_ERRCTRL_SRC_COUNT
} co_errctrl_source;

/* Emit an error-control event (u.errctrl). guarded: seen through node
 * guarding rather than heartbeat. */
void co_errctrl_emit(co_node *node, co_event_kind kind, uint8_t remote, uint8_t state, uint8_t prev,
		     bool guarded, uint16_t time_ms);

/* A communication loss happened (src now reports a loss): EMCY 8130h with
 * msef[0] = msef_node, then 1029h:1 (may change the NMT state). */
void co_errctrl_comm_lost(co_node *node, co_errctrl_source src, uint8_t msef_node, uint64_t now_us);
/* src reports whether it still has a loss; when no source has one, EMCY
 * 8130h is cleared (nothing happens if it was not active). */
void co_errctrl_loss_update(co_node *node, co_errctrl_source src, bool lost, uint64_t now_us);

/* The guarding master polls (on) or stopped polling (off) `remote`. */
void co_errctrl_guarded_set(co_node *node, uint8_t remote, bool on);
bool co_errctrl_guarded(const co_node *node, uint8_t remote);

#endif /* COGW_CORE_ERRCTRL_H */
