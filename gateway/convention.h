/* SPDX-License-Identifier: MIT */
/*
 * gateway/convention.h - the encodings this project defines for CiA 302-7
 * multi-level networking, in one place (docs/gateway.md). CiA 302-7 names
 * the objects; where this project had to choose their layout, the choice
 * is here, and when it must change, this file (and its unit test) is what
 * changes.
 *
 *   network indication   client -> gateway SDO server, before a routed
 *                        transfer: E0 nn nn id 00 00 00 00 (nn = target
 *                        network, UNSIGNED16 LE; id = target node). The
 *                        gateway confirms with E0 and the same bytes 1..3,
 *                        or refuses with an SDO abort (80, bytes 1..3 =
 *                        network/node, bytes 4..7 = the code below).
 *   1F2Ch:n              route to network n (UNSIGNED32): bits 0..7 = local
 *                        line + 1 (0 = not reachable), bits 8..15 = node-ID
 *                        of the next router on that line (0 = attached
 *                        directly), bits 16..31 = 0.
 *   1F2Fh:n              pairs with 1028h:n: bit k-1 set = forward that
 *                        node's EMCY to network k (networks 1..32).
 *   forwarded EMCY       code F000h, byte 2 = the gateway's error register,
 *                        bytes 3..4 = source network (LE), byte 5 = source
 *                        node, bytes 6..7 = the original error code (LE).
 *
 * Pure functions, no state: any thread may call them.
 */
#ifndef COGW_GATEWAY_CONVENTION_H
#define COGW_GATEWAY_CONVENTION_H

#include <stdbool.h>
#include <stdint.h>

#include "core/sdo.h"

#define GW_NET_MIN 1u
#define GW_NET_MAX 127u  /* network ids 1..127 (1F2Ch sub-indexes) */
#define GW_LINES_MAX 16u /* lines a daemon drives (config limit) */

#define GW_OBJ_ROUTES 0x1F2Cu      /* routing table */
#define GW_OBJ_EMCY_ROUTES 0x1F2Fu /* EMCY routing */
#define GW_OBJ_NETWORK_ID \
	0x5F00u                /* this line's own network id (U8 ro);
                                    * manufacturer-specific area, so that
                                    * it cannot clash with a CiA object */
#define GW_IMAGE_FIRST 0xB000u /* shared process image */
#define GW_IMAGE_LAST 0xBFFFu

/* ---- abort codes: which situation answers with which code ------------- */
#define GW_AB_NET_UNKNOWN \
	SDO_AB_NET_UNKNOWN /* 0A000001: no route to the
                                               * network, or the route leads
                                               * back where the request came
                                               * from (a loop) */
#define GW_AB_NO_ANSWER \
	SDO_AB_NODE_UNKNOWN /* 0A000002: the target node is
                                               * known silent, its line is
                                               * down or bus-off, or it never
                                               * answered */
#define GW_AB_ROUTE_BUSY \
	SDO_AB_ROUTE_BUSY /* 0A000003: the hand-off to
                                               * the target line is full */
#define GW_AB_NO_CLIENT \
	SDO_AB_NO_RESOURCE /* 060A0023: no SDO client of
                                               * the target line is free */

/* ---- network indication ------------------------------------------------ */
#define GW_NETIND_CS 0xE0u /* byte 0: command specifier 7, other bits 0 */

typedef struct gw_netind {
	uint16_t net; /* target network 1..127 */
	uint8_t node; /* target node 1..127 */
} gw_netind;

/* True if byte 0 says "network indication" (command specifier 7). */
static inline bool gw_netind_is(const uint8_t d[8])
{
	return (d[0] >> 5) == 7u;
}
/* Decode a network indication (or its confirmation). Returns 0, or the
 * abort code to refuse it with: SDO_AB_CMD when byte 0 is not exactly
 * E0h or bytes 4..7 are not 0, GW_AB_NET_UNKNOWN for a network outside
 * 1..127, GW_AB_NO_ANSWER for a node outside 1..127. *out is filled with
 * bytes 1..3 in every case (for the abort frame). */
uint32_t gw_netind_decode(const uint8_t d[8], gw_netind *out);
/* Indication and confirmation have the same layout. */
void gw_netind_encode(uint8_t d[8], gw_netind ni);
/* An SDO abort: 80, bytes 1..3 = mux (index, sub-index, or what the
 * aborted frame carried there), bytes 4..7 = code. */
void gw_sdo_abort_encode(uint8_t d[8], const uint8_t mux[3], uint32_t code);
/* The refusal: 80, bytes 1..3 = network/node, bytes 4..7 = code. */
void gw_netind_abort_encode(uint8_t d[8], gw_netind ni, uint32_t code);

/* ---- 1F2Ch entries ----------------------------------------------------- */
typedef struct gw_route_entry {
	bool reachable; /* bits 0..7 != 0 */
	uint8_t line;   /* 0-based local line (valid if reachable) */
	uint8_t router; /* next router's node-ID, 0 = network attached */
} gw_route_entry;

uint32_t gw_route_entry_encode(gw_route_entry e);
/* Returns 0, or SDO_AB_VALUE when bits 16..31 are set, the router is
 * outside 0..127, a router is given for an unreachable network, or the
 * line is not one of the n_lines lines of this daemon. */
uint32_t gw_route_entry_decode(uint32_t v, uint8_t n_lines, gw_route_entry *out);

/* ---- 1F2Fh entries ----------------------------------------------------- */
#define GW_EMCY_NETS 32u /* an UNSIGNED32 names networks 1..32 */
static inline bool gw_emcy_route_has(uint32_t bits, uint16_t net)
{
	return net >= 1 && net <= GW_EMCY_NETS && (bits >> (net - 1)) & 1u;
}

/* ---- forwarded EMCY ---------------------------------------------------- */
#define GW_EMCY_FWD_CODE 0xF000u

typedef struct gw_emcy_fwd {
	uint8_t err_reg;  /* the gateway's own 1001h on the sending line */
	uint16_t src_net; /* network the EMCY was consumed on */
	uint8_t src_node; /* its producer */
	uint16_t code;    /* its error code */
} gw_emcy_fwd;

void gw_emcy_fwd_encode(uint8_t d[8], const gw_emcy_fwd *e);
/* -EINVAL unless bytes 0..1 are F000h (not a forwarded EMCY). */
int gw_emcy_fwd_decode(const uint8_t d[8], gw_emcy_fwd *out);

#endif /* COGW_GATEWAY_CONVENTION_H */
