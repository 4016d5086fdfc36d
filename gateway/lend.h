/* SPDX-License-Identifier: MIT */
/*
 * gateway/lend.h - what a line lends to the routed SDO transfers of other
 * lines, published so that the entry line decides a network indication at
 * once instead of asking the target line and waiting for its answer
 * (docs/gateway.md, "Leases without a round trip").
 *
 * The owner (the target line's thread) publishes whether it carries frames
 * and which nodes its heartbeat consumer has lost; its SDO client pool
 * (core/sdo_client.h gate, gw_lend_gate) keeps the rest up to date: the
 * channels nobody holds (a set), and per server (node-ID) whether it is in
 * a transfer of its own, settling after one, or reserved for a lease. A
 * requester's line reserves one channel and the node by compare-and-swap
 * (gw_lend_reserve): of two claimants of one unit, the owner's pool or
 * another line, exactly one wins. The owner binds the lease on the
 * reserved unit when the request reaches it; a reservation whose request
 * never reaches it goes back with gw_lend_give_back, once.
 *
 * Threads: gw_lend_reserve, gw_lend_claim_node, gw_lend_give_back and the
 * offer's calls from any line; the rest by the owner only. Release stores, acquire loads: a requester that sees
 * "carries" sees the sets published before it.
 */
#ifndef COGW_GATEWAY_LEND_H
#define COGW_GATEWAY_LEND_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>

#include "core/sdo_client.h"

#define GW_LEND_CHANNELS 128u /* the sets' width: client channels 0..127 */

#define GW_LEND_CHANNELS 128u /* client channels 0..127 */

typedef struct gw_lend {
	_Atomic bool carries;        /* the owner's last look at its link */
	_Atomic uint64_t silent[2];  /* heartbeat-lost nodes, bit n */
	_Atomic uint64_t free_ch[2]; /* client channels nobody holds, bit ch */
	/* Per node-ID, its server: 0 free, else held (busy, settling,
	 * reserved or leased), and for a lease that ended well who may take
	 * it over (gw_lend_offer): one word, so that the owner's end of such
	 * a lease frees the node and withdraws the offer in one step. */
	_Atomic uint32_t node[128];
} gw_lend;

/* Nothing to lend, not carrying, until the owner publishes. */
void gw_lend_init(gw_lend *b);

/* ---- the owner ---- */
void gw_lend_set_carries(gw_lend *b, bool carries);
void gw_lend_set_silent(gw_lend *b, const uint64_t lost[2]);
bool gw_lend_is_silent(const gw_lend *b, uint8_t node);
/* The gate of the owner's SDO client pool (sdo_client_set_gate, ctx = b). */
bool gw_lend_gate(void *ctx, sdo_client_gate_op op, uint8_t arg);

/* The lease bound on a reservation for node ended: the node is free again.
 * After sdo_client_lease_end has given the channel back through the gate
 * (a transfer toward the node that finds it free finds the channel free
 * as well), then sdo_client_gate_kick: the pool's requests waiting for
 * that node start. */
void gw_lend_node_free(gw_lend *b, uint8_t node);
/* Line `from`'s lease (channel ch, node) reaches its M_CLOSE: if the
 * next transfer took it (gw_lend_reserve, gw_lend_take_offer), it is kept
 * for that transfer: the node that transfer goes to, *taker its line (the
 * node stays held, or is freed if that node differs). 0: not taken,
 * nothing changed. */
uint8_t gw_lend_hand_over(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t *taker);
/* The end of that lease once its channel is back (through the gate), in
 * one step: the node freed if an offer still stands or none was made
 * (0), or, taken meanwhile, as gw_lend_hand_over. The channel first: a
 * transfer toward the node that finds it free finds the channel free as
 * well; one that takes the offer in between gets the channel back
 * (gw_lend_claim_channel) bound to its lease. */
uint8_t gw_lend_end_offered(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t *taker);
/* Take channel ch back from the free ones for such a lease: false when
 * something else took it (the owner's pool, another reservation). */
bool gw_lend_claim_channel(gw_lend *b, uint8_t ch);
/* ---- any line ---- */
/* Reserve a channel and node `node` of the owner for one lease of line
 * `from`. 0 and *channel, or the refusal, in this order: GW_AB_NO_ANSWER
 * (not carrying, the node heartbeat-lost), sdo_abort_of_errno(-EALREADY)
 * (the node busy or settling, or reserved by another), GW_AB_NO_CLIENT
 * (no free channel). A lease toward node that ended well and is still
 * offered - of `from` or of another line - is taken instead (*taken true,
 * *channel its channel): the owner keeps it for `from`'s M_OPEN. */
uint32_t gw_lend_reserve(gw_lend *b, uint8_t from, uint8_t node, uint8_t *channel, bool *taken);
/* Take node alone, for a transfer that takes its line's lease of another
 * node (gw_lend_take_offer): false when it is held. */
bool gw_lend_claim_node(gw_lend *b, uint8_t node);
/* A reservation that will not be bound (node 0: its channel alone;
 * channel GW_LEND_NONE: its node alone). */
#define GW_LEND_NONE 0xFFu
void gw_lend_give_back(gw_lend *b, uint8_t channel, uint8_t node);

/* ---- a lease handed from one transfer of a line to its next ----
 * A requester's line whose lease ended well (the device idle) sends
 * M_CLOSE; its next transfer to that line may come before the owner took
 * it, and would find the node, or every channel, still held by it. So the
 * line offers the lease in the node's word before the M_CLOSE leaves; its
 * next transfer takes it (gw_lend_reserve for the same node,
 * gw_lend_take_offer for another), or the owner's end of the lease
 * withdraws the offer and frees the node in the same compare-and-swap
 * (gw_lend_end_offered): exactly one wins, and a transfer that loses
 * finds the node free. A taken lease stays bound on the owner (moved to
 * the next transfer's node) for the M_OPEN that follows its M_CLOSE in
 * the ring; nothing of the owner's own pool gets between the two. */

/* Line `from` closes its lease (node, ch) well: before its M_CLOSE is
 * pushed. */
void gw_lend_offer(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch);
/* That M_CLOSE was not pushed: the offer goes (the lease's idle limit
 * frees it). */
void gw_lend_withdraw(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch);
/* Take line `from`'s offered lease (node, ch) for its next transfer, to
 * new_node (claimed by the caller: gw_lend_claim_node): true when the
 * owner had not ended it. */
bool gw_lend_take_offer(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t new_node);
/* That transfer's M_OPEN was not pushed (`from`: the line that took it):
 * an offer again. false: the owner kept the lease for it already (its
 * idle limit frees it). */
bool gw_lend_untake(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t new_node);

#endif /* COGW_GATEWAY_LEND_H */
