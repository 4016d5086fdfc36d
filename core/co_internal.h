/* SPDX-License-Identifier: MIT */
/*
 * core/co_internal.h - the node as the built-in services of core/ see it:
 * the fields of struct co_node, with one typed slot per service, and what
 * only core/ calls. The application API, and what any service may call
 * (receive dispatch, events, deadlines, the service ops), stay in
 * core/co.h. Include it from the .c files of core/ only
 * (and from unit tests of core internals). Same threading rule as
 * core/co.h: owning thread only.
 *
 * How to add a service: see core/co.h.
 */
#ifndef COGW_CORE_CO_INTERNAL_H
#define COGW_CORE_CO_INTERNAL_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

/* Tell every service (nmt_changed op) that the NMT state changed. Called
 * by core/nmt.c only. */
void co_node_nmt_changed(co_node *node, uint8_t new_state, uint64_t now_us);

struct co_rx;
struct co_rx_ext;
struct sdo_server;
struct sdo_client;
struct co_store;
struct co_nmt;
struct co_errctrl;
struct co_hb;
struct co_guard;
struct co_emcy;
struct co_commfault;
struct co_sync;
struct co_time;
struct co_pdo;
struct co_lss;

/* Fields are private to core/ services: applications use the functions. */
struct co_node {
	co_node_config cfg; /* copy, with defaults filled in */
	co_od *od;
	uint8_t node_id;
	uint64_t deadline_us; /* cached minimum of the services' deadlines */
	uint64_t now_us;      /* time of the current recv/tick call */
	co_node_stats stats;

	/* receive dispatch */
	uint16_t rx_sff[2048];    /* head receiver + 1 per 11-bit id, 0 = none */
	struct co_rx *rx;         /* pool of cfg.rx_max receivers */
	uint16_t rx_free;         /* free list head + 1 */
	struct co_rx_ext *rx_ext; /* sorted by id, cfg.rx_ext_max entries */
	uint16_t rx_ext_count;

	/* service slots: NULL until the module exists / is enabled */
	struct sdo_server *sdo_srv; /* core/sdo_server.c */
	struct sdo_client *sdo_cli; /* core/sdo_client.c */
	struct co_store *store;     /* core/store.c (1010h/1011h) */
	struct co_nmt *nmt;         /* core/nmt.c */
	struct co_errctrl *errctrl; /* core/errctrl.c: what heartbeat and
	                             * guarding share (losses) */
	struct co_hb *hb;           /* core/heartbeat.c: producer/consumer */
	struct co_guard *guard;     /* core/guarding.c: node guarding, master
	                             * and slave (100Ch/100Dh) */
	struct co_emcy *emcy;       /* core/emcy.c */
	struct co_sync *sync;       /* core/sync.c */
	struct co_time *time;       /* core/time.c */
	struct co_pdo *pdo;         /* core/pdo.c */
	struct co_lss *lss;         /* core/lss_service.c: master and slave */

	/* core/commfault.c: controller states, lost frames, node-ID collision */
	struct co_commfault *commfault;
};

#endif /* COGW_CORE_CO_INTERNAL_H */
