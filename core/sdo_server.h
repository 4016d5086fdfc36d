/* SPDX-License-Identifier: MIT */
/*
 * core/sdo_server.h - SDO server channels (CiA 301 §7.2.4, objects
 * 1200h..127Fh): expedited, segmented and block transfer, upload and
 * download, block CRC, per-frame timeout.
 *
 * Channels: cfg.sdo_server_count of them (co.h). Channel 0 uses 1200h if the
 * OD has it, else the predefined 600h+id / 580h+id. Channels 1.. use
 * 1201h.. and are created in the OD (COB-IDs invalid) if absent. Writing
 * sub 1/2 follows CiA 301: bit 31 = invalid; a valid COB-ID may only be
 * changed (to another valid id) while the channel is invalid, otherwise
 * 0x06090030.
 *
 * Download data path (why two):
 * - Entries whose capacity (max_size) is at most cfg.sdo_stage_size bytes
 *   (all numerics, short strings) are staged in the channel and only stored
 *   after the length/limit checks and the check_write hook accepted them,
 *   so a refusal leaves the value unchanged.
 * - Larger entries (big strings and DOMAINs, 100 KiB firmware images) are
 *   written in place as the data arrives; the check_write hook then runs at initiate with
 *   data == NULL and size = the indicated size, and after_write runs at the
 *   end. An aborted in-place download leaves a partial value; the
 *   application sees no CO_EV_OD_WRITTEN for it.
 *
 * NMT: in STOPPED the server ignores every request (no answer, no abort:
 * CiA 301 allows only NMT and error control there); entering STOPPED ends
 * a transfer in progress without a frame (CO_EV_SDO_SERVER_DONE with
 * 0x08000022).
 *
 * Block transfers answer sc = cc: the CRC is used only when the client
 * asked for it.
 *
 * Deferred answers: a read, check_write or check_streamed hook (the last
 * at the end of an in-place download, before the value is committed)
 * returning CO_OD_DEFERRED parks the channel. No reply goes out until sdo_server_continue() is
 * called (the per-frame timeout keeps running; when it expires the server
 * aborts with 0x05040000 and a later continue returns -ENOENT).
 */
#ifndef COGW_CORE_SDO_SERVER_H
#define COGW_CORE_SDO_SERVER_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/sdo.h"

extern const co_service co_svc_sdo_server;

/*
 * Finish a deferred access on server channel `channel`.
 * - abort != 0: the transfer is aborted with that code.
 * - deferred read, abort == 0: data/size give the value to upload; the
 *   buffer must stay valid until CO_EV_SDO_SERVER_DONE for this channel.
 *   data == NULL uploads the entry's current value instead (the hook may
 *   have refreshed it).
 * - deferred write, abort == 0: the staged value is stored (after_write
 *   runs, CO_EV_OD_WRITTEN is emitted) and the download is confirmed;
 *   data/size are ignored.
 * Call it after the hook has returned CO_OD_DEFERRED (from a later event,
 * a mailbox command, another line's completion), never from inside it.
 * Returns 0, -ENOENT if the channel is not waiting for a continue (e.g.
 * it timed out or the client aborted; CO_EV_SDO_SERVER_DONE told so),
 * -EINVAL for a bad channel.
 */
int sdo_server_continue(co_node *node, uint8_t channel, uint32_t abort, const uint8_t *data,
			uint32_t size, uint64_t now_us);

/*
 * CiA 302-7 routing hook (used by gateway/; docs/gateway.md).
 * A frame with command specifier 7 (a network indication) arriving on an
 * idle channel goes to ops->indication. The channel is then "routed":
 * every later frame received on it goes to ops->frame untouched (aborts
 * included); the server neither answers nor times out on it until
 * sdo_server_route_end(). ops->frame returns false when it did not take
 * the frame because the route ended just before it (the hook learnt only
 * then that the transfer had ended, and called sdo_server_route_end):
 * the server then handles the frame as a new request. If indication returns an abort code instead of
 * 0, the server refuses with it (bytes 1..3 = those of the indication) and
 * the channel stays idle. ops->ended tells that the server itself ended a
 * route (its COB-IDs changed, reset communication): the hook must forget
 * the channel. Without a hook, command specifier 7 is refused with
 * 05040001 as any unknown one. No CO_EV_SDO_SERVER_DONE for routed
 * transfers: the routing layer reports them.
 * Callbacks run on the node's thread, inside co_node_recv / the call that
 * reset the node.
 */
typedef struct sdo_server_route_ops {
	uint32_t (*indication)(void *ctx, uint8_t channel, const uint8_t d[8], uint64_t now_us);
	bool (*frame)(void *ctx, uint8_t channel, const uint8_t d[8], uint64_t now_us);
	void (*ended)(void *ctx, uint8_t channel);
} sdo_server_route_ops;

/* Install (ops = NULL: remove) the hook. -EINVAL, -EBUSY while a channel
 * is routed. */
int sdo_server_route_attach(co_node *node, const sdo_server_route_ops *ops, void *ctx);
/* Send 8 bytes on a routed channel's server->client COB-ID. -ENOENT if
 * the channel is not routed, else what the send callback returned. */
int sdo_server_route_send(co_node *node, uint8_t channel, const uint8_t d[8]);
/* The frame sdo_server_route_send would send (COB-ID, flags, 8 bytes),
 * for a sender on another thread (docs/gateway.md, frames across
 * interfaces). -ENOENT if the channel is not routed. */
int sdo_server_route_frame(co_node *node, uint8_t channel, const uint8_t d[8], co_frame *out);
/* Give a routed channel back to the server. -ENOENT if not routed. */
int sdo_server_route_end(co_node *node, uint8_t channel);

/* True while a transfer is in progress on the channel. */
bool sdo_server_busy(const co_node *node, uint8_t channel);
/* Name of the channel's state ("idle", "download segment", "block upload
 * ack", "deferred", "routed", ...); "?" for a bad channel. */
const char *sdo_server_state_to_string(const co_node *node, uint8_t channel);
uint8_t sdo_server_channel_count(const co_node *node);

#endif /* COGW_CORE_SDO_SERVER_H */
