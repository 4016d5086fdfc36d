/* SPDX-License-Identifier: MIT */
/*
 * core/od_std.h - the standard communication objects of one node (CiA 301
 * §7.5.2), created in one call with CiA 301 types, access and defaults.
 *
 * Who uses it: cogwd's configuration (apps/common/config.c) builds every
 * line's OD with it before the node exists; the device simulator and unit
 * tests use it for their slaves. The services then find their objects in
 * the OD at init (co_node_create) and hook them.
 *
 * What it creates (entries that already exist are kept, so a caller may
 * pre-create any object with other limits or defaults):
 *   1000h device type             UNSIGNED32 ro
 *   1001h error register, 1003h pre-defined error field (history subs),
 *   1014h COB-ID EMCY (80h+id), 1015h inhibit time EMCY, 1028h EMCY
 *         consumers                                    (co_od_add_comm_defaults_emcy)
 *   1005h COB-ID SYNC, 1006h period, 1007h window, 1019h counter overflow
 *                                                      (co_od_add_comm_defaults_sync)
 *   1008h/1009h/100Ah device name / hardware / software version
 *                                 VISIBLE_STRING const
 *   100Ch guard time, 100Dh life time factor           (co_od_add_comm_defaults_guard)
 *   1010h store / 1011h restore parameters: ARRAY of UNSIGNED32 rw, value =
 *         capability 1 (on command); core/store.c hooks them
 *   1012h COB-ID TIME (100h: neither consumer nor producer)
 *   1016h consumer heartbeat time (hb_consumers subs, all 0 = off), 1017h
 *         producer heartbeat time                      (co_od_add_comm_defaults_hb)
 *   1018h identity: sub 0 = 4, subs 1..4 UNSIGNED32 ro
 *   1029h error behaviour, 102Ah NMT inhibit time      (co_od_add_comm_defaults_nmt)
 *   1200h SDO server 1: sub 0 = 2, subs 1/2 UNSIGNED32 ro 600h+id / 580h+id
 *         (the predefined connection set, CiA 301 §7.3.3)
 *   1201h.. further SDO servers, 1280h.. SDO clients: sub 0 = 3, subs 1/2
 *         UNSIGNED32 rw 8000 0000h (not valid), sub 3 UNSIGNED8 rw node-id 0
 *   1400h/1600h.. RPDOs, 1800h/1A00h.. TPDOs (co_od_add_pdo): PDO 1..4 get
 *         the predefined COB-IDs 200h/300h/400h/500h + id (RPDO) and
 *         180h/280h/380h/480h + id (TPDO), further PDOs 8000 0000h; with
 *         pdo_valid false (default) bit 31 is set on all of them, so that
 *         no PDO runs before the integrator has mapped it. Transmission type
 *         255 (event-driven, manufacturer specific), 8 mapping entries.
 *   1F2Ch/1F2Fh (gateway = true): CiA 302-7 routing table, 127 subs, and
 *         EMCY routing, one sub per 1028h sub; UNSIGNED32 rw, 0 (see
 *         docs: "Conventions this project defines").
 *
 * Call at OD build time only (allocates). Returns 0, -EINVAL (bad node id
 * or option), -ENOMEM, or -EEXIST when a PDO record exists only in part.
 */
#ifndef COGW_CORE_OD_STD_H
#define COGW_CORE_OD_STD_H

#include <stdbool.h>
#include <stdint.h>

#include "core/od.h"

#define CO_OD_STD_STRING_MAX 64u /* capacity of 1008h/1009h/100Ah */

typedef struct co_od_std_opts {
	uint32_t device_type;    /* 1000h (default 0: no profile) */
	const char *device_name; /* 1008h (default "cogw") */
	const char *hw_version;  /* 1009h (default "") */
	const char *sw_version;  /* 100Ah (default "") */
	uint32_t vendor_id;      /* 1018h:1..4 (default 0) */
	uint32_t product_code;
	uint32_t revision;
	uint32_t serial;

	uint8_t emcy_history;         /* 1003h subs, 0 = no 1003h (default 8) */
	uint8_t emcy_consumers;       /* 1028h subs, 0 = none (default 127) */
	bool emcy_consume_all;        /* 1028h:n valid for every n except our own
	                         * id (default true: a manager listens) */
	uint8_t hb_consumers;         /* 1016h subs (default 127) */
	uint16_t heartbeat_ms;        /* 1017h (default 0) */
	uint32_t sync_cob_id;         /* 1005h (default 80h: consumer only) */
	uint32_t sync_period_us;      /* 1006h (default 0) */
	uint8_t sync_overflow;        /* 1019h (default 0) */
	uint32_t time_cob_id;         /* 1012h (default 100h) */
	uint8_t store_subs;           /* 1010h/1011h subs, 0 = none (default 3) */
	uint8_t error_behaviour_subs; /* 1029h subs (default 1) */
	uint8_t sdo_servers;          /* 1200h.. count, 1..128 (default 1) */
	uint8_t sdo_clients;          /* 1280h.. count, 0..128 (default 0) */
	uint16_t rpdos;               /* 0..512 (default 0) */
	uint16_t tpdos;               /* 0..512 (default 0) */
	bool pdo_valid;               /* PDO 1..4 valid by default (default false) */
	bool gateway;                 /* 1F2Ch/1F2Fh (default false) */
} co_od_std_opts;

/* Fill *o with the defaults named above. */
void co_od_std_opts_init(co_od_std_opts *o);

/* Add the objects above for node_id (1..127). opts NULL = defaults. */
int co_od_add_std_comm(co_od *od, uint8_t node_id, const co_od_std_opts *opts);

#endif /* COGW_CORE_OD_STD_H */
