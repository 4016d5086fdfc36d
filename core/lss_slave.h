/* SPDX-License-Identifier: MIT */
/*
 * core/lss_slave.h - LSS slave (CiA 305), for devices (the simulated ones
 * in tests and demos) and for any node whose node-ID comes from LSS.
 *
 * Enabled by cfg.lss_slave (see core/co.h). Listens on 7E5h, answers on
 * 7E4h.
 *
 * Contract
 * - States: waiting (after start-up) and configuration. Node-ID and bit
 *   timing are configured only in configuration state; identify and
 *   Fastscan work in waiting state (identify remote and identify
 *   non-configured in both).
 * - Three node-IDs (CiA 305): persistent (what the application stored, =
 *   cfg.node_id at creation), pending (set by configure node-ID) and active
 *   (what the node uses, co_node_id()).
 *     configure node-ID  -> pending (1..127, or 255 = unconfigured; else
 *                           error 1 "out of range")
 *     reset communication -> active = pending (node->node_id changes)
 *     store configuration -> persistent = pending, through the store hook
 *                           or, without one, CO_EV_LSS_SLAVE_STORE; the
 *                           application saves it and hands it back as
 *                           cfg.node_id next time.
 *   A node started unconfigured (255) that got a valid pending node-ID
 *   performs reset communication by itself when it is switched back to
 *   waiting state.
 * - cfg.lss_slave_constant_id: the node-ID is fixed by the device (a
 *   switch, a constant): store answers error 1 "not supported".
 * - Identity: read from 1018h:1..4 on every use (missing subs read as 0).
 * - Bit timing: the hooks decide; without hooks the CiA table (selector
 *   0, indexes 0-4 and 6-8) is accepted. Activate bit timing emits
 *   CO_EV_LSS_SLAVE_BIT_TIMING; switching the controller (after the
 *   delay) is the application's job.
 * - Events: CO_EV_LSS_SLAVE_STATE, _NODE_ID, _STORE, _BIT_TIMING (all
 *   u.lss_slave).
 */
#ifndef COGW_CORE_LSS_SLAVE_H
#define COGW_CORE_LSS_SLAVE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/lss.h"

/* Application hooks (cfg.lss_slave_hooks, all optional, ctx =
 * cfg.lss_slave_ctx). They run synchronously in the receive path and
 * return an LSS error code (LSS_EC_*); *spec is the implementation
 * specific byte sent with LSS_EC_SPECIFIC. */
typedef struct lss_slave_hooks {
	/* May the device use this bit timing? (configure bit timing) */
	uint8_t (*check_bit_timing)(void *ctx, uint8_t table, uint8_t index, uint8_t *spec);
	/* Save node_id and the bit timing (table/index; bt_valid false when
	 * none was configured) persistently. */
	uint8_t (*store)(void *ctx, uint8_t node_id, bool bt_valid, uint8_t table, uint8_t index,
			 uint8_t *spec);
} lss_slave_hooks;

/* Current state and node-IDs; -ENODEV without an LSS slave. Any out
 * pointer may be NULL. */
int lss_slave_get(const co_node *node, lss_state *state, uint8_t *active, uint8_t *pending,
		  uint8_t *persistent);

/* ---- for core/lss_service.c only ---------------------------------------------- */
int lss_slave_init(co_node *node, struct lss_slave **out);
void lss_slave_fini(struct lss_slave *s);
void lss_slave_reset_comm(struct lss_slave *s, uint64_t now_us);

#endif /* COGW_CORE_LSS_SLAVE_H */
