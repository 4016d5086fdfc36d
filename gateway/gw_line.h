/* SPDX-License-Identifier: MIT */
/*
 * gateway/gw_line.h - the gateway's run-time state, shared by the files of
 * gateway/ that run it on the line threads (not a public header: see
 * gateway.h).
 *
 * Who does what (calls go down this list, never back up):
 *   gateway.c      the extension ops and the life cycle: every message
 *                  and every tick enters here and goes to one of
 *   gw_session.c   routed sessions of the entry line (network indications
 *                  on its SDO server, gateway/sdo_route.h)
 *   gw_mbx_hop.c   the routing step of the line's mailbox SDO transfers
 *                  (lines/line_sdo.c; line_ext.h sdo_route)
 *   gw_relay.c     relay leases of the target line (its SDO clients lent
 *                  to sessions and mailbox transfers of any line)
 *   gw_emcy.c      EMCY routing (1F2Fh) at run time
 *   gw_pdo.c       PDO forwarding of the B-objects at run time
 *   gw_status.c    the mailbox's GW_ROUTES answer
 *   gw_hand_off.c  the one way a message leaves a line (the rings)
 *
 * Each gw_line belongs to its line thread. The only thing another thread
 * reads is the counters (relaxed atomics, gw_line_counters_get) and, for
 * PDO forwarding, the other lines' forwarding lists and lost-update marks
 * (gateway/pdo_sync.h, atomics), their fast TPDOs (gateway/fast_tpdo.h,
 * atomics), their done_from counts, the peer_fd socket that belongs to
 * the reading line (written before the lines start; it carries fast TPDOs
 * and the frames of routed SDO transfers sent across, gw_send_across),
 * and, for routed SDO, their lending boards (gateway/lend.h, atomics: a
 * requester's line reserves a client channel and the node there) and the
 * answer records of their sessions (struct gw_across). Everything else
 * crosses lines as a gw_msg, by value.
 */
#ifndef COGW_GATEWAY_GW_LINE_H
#define COGW_GATEWAY_GW_LINE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/sdo_server.h"
#include "gateway/fast_tpdo.h"
#include "gateway/gateway.h"
#include "gateway/image.h"
#include "gateway/lend.h"
#include "gateway/pdo_sync.h"
#include "gateway/route.h"
#include "gateway/sdo_route.h"
#include "lines/line.h"
#include "lines/xring.h"

#define GW_RELAYS_MAX 128u
#define GW_RING_SLOTS 1024u
#define GW_RELAY_IDLE_FACTOR 8u  /* idle lease given back after 8 timeouts */
#define GW_REBUILD_US 1000000u   /* forwarding list re-checked every 1 s */
#define GW_LINK_CHECK_US 100000u /* link of a line holding leases: every 100 ms */
#define GW_DRAIN_US 100000u      /* an aborted lease: quiet time before it is free */
#define GW_HOPS_MAX 64u          /* routed mailbox SDO transfers per line */
#define GW_SELF_SLOTS 64u        /* messages a line hands to itself */
#define GW_QUIET_WAKE_AT 64u     /* quiet messages queued before they wake the target */
#define GW_CLOSING_MAX 4u        /* leases closed well remembered per target line */

enum gw_msg_kind {
	M_FWD = 1,   /* a B-object changed: slot, its new value in bits */
	M_EMCY,      /* send a forwarded EMCY: net, src_node, code */
	M_OPEN,      /* bind the lease reserved for sid: channel toward node */
	M_TO_TARGET, /* a requester frame: d */
	M_TO_REQ,    /* a target frame: d */
	M_CLOSE,     /* give the lease of sid back */
	M_LOST,      /* sid ends with abort: the target line carries no frames
	              * (link down, bus-off), or the reserved lease could not be
	              * bound (the state changed since the reservation) */
};

/* Who puts the frame of an M_TO_TARGET / M_TO_REQ on the bus
 * (gw_send_across): the line it is for (a hand-off), or the sender, which
 * already did on its socket bound to that line's interface (the message
 * only tells the owner of the transfer's state), or the sender tried and
 * could not (the owner sends it, its state already saw the frame). */
enum gw_frame_sent {
	GW_OWNER_SENDS = 0,
	GW_SENT_ACROSS,
	GW_SEND_FAILED,
};

/* Everything that crosses lines, by value. */
typedef struct gw_msg {
	uint8_t kind;
	uint8_t from;   /* sending line */
	uint8_t node;   /* M_OPEN: target or router; M_EMCY: source node */
	uint8_t sent;   /* M_TO_TARGET, M_TO_REQ: enum gw_frame_sent */
	uint32_t sid;   /* what a lease serves: see gw_sid_* */
	uint32_t abort; /* M_LOST */
	uint16_t slot;  /* M_FWD */
	uint16_t net;   /* M_EMCY: source network */
	uint16_t code;  /* M_EMCY: original error code */
	uint64_t bits;  /* M_FWD: the value written (gw_image_bits_from) */
	uint8_t d[8];   /* frames */
	/* M_OPEN of a session: the frame its answers leave on (the server
	 * channel's COB-ID and flags), for the lease to send them across;
	 * reply_id 0: a mailbox hop, whose answers go back as messages */
	uint32_t reply_id;
	uint8_t reply_flags;
	/* M_OPEN: the client channel reserved (gw_lend_reserve); M_TO_TARGET,
	 * M_CLOSE: the lease's channel, its slot on the target (relay[]) */
	uint8_t channel;
	/* M_TO_REQ sent across: its record in the session's gw_across */
	uint32_t across_seq;
	/* M_FWD: fast TPDOs of the target (gateway/fast_tpdo.h, bit k) the
	 * source sent at sent_us (their numbers in fast_nr), and those it
	 * counted as held */
	uint32_t fast_sent, fast_held;
	uint64_t sent_us;
	uint16_t fast_nr[GW_FAST_SENT_MAX];
	uint8_t n_fast;
	/* M_OPEN: the lease is the sender's own that ended well on this
	 * channel just before (its M_CLOSE is ahead in the ring), taken from
	 * the lending board's handover (gw_lend_take_offer) and kept parked
	 * by the target; claimed_node: the sender claimed `node` on the
	 * board itself (the parked lease was toward another node) */
	bool inherits, claimed_node;
} gw_msg;

/* A lease serves a session (bit 23 clear: line << 24 | channel << 16 |
 * generation) or a mailbox transfer's hop (bit 23 set: line << 24 | hop
 * << 16 | generation) of the line `sid >> 24`. */
#define GW_SID_HOP 0x800000u

struct gw_line;

/* The last answer a target line sent across to a session's requester,
 * published before the frame left (single writer: that line's thread; a
 * sequence lock). The requester may answer it before the entry line has
 * taken the M_TO_REQ that tells the session; the session looks here
 * first (docs/gateway.md, "Frames across interfaces"). */
struct gw_across {
	_Atomic uint32_t seq; /* odd while written */
	_Atomic uint32_t sid;
	_Atomic uint64_t d; /* the 8 bytes, little-endian */
};

/* A routed session: one per SDO server channel of the entry line. */
struct gw_sess {
	struct gw_line *gl;
	uint8_t ch;
	uint16_t gen;
	uint16_t net; /* the requested network (for the counters) */
	uint8_t target_line;
	bool lease_lost;     /* the target line ended the lease (M_LOST) */
	bool target_aborted; /* the last frame relayed to the target was an abort */
	uint8_t lease_ch;    /* the target line's client channel it holds */
	uint64_t started_us; /* the network indication (for the listing) */
	/* pushed_to[target_line] after the session's last hand-off there: a
	 * frame goes across only once that line has done it (gw_send_across) */
	uint64_t handoff_seq;
	/* the target's frame being delivered was already sent to the
	 * requester by the target line: to_requester skips exactly it */
	bool answered_across;
	uint8_t across[8];
	/* per target line, the answers it sent across (written there), and
	 * the record of across[target_line] this session last applied */
	struct gw_across answer[GW_LINES_MAX];
	uint32_t across_taken;
	/* the server channel's frame (COB-ID, flags) when the lease was
	 * asked: what an answer the lease could not send across is sent on,
	 * even after the session ended on its message */
	co_frame reply;
	gw_sdo_route r;
};

/* A relay lease: one SDO client channel of the target line lent out. */
struct gw_relay {
	bool used;
	/* The line stopped carrying frames under it (link down, bus-off):
	 * the session was told and is gone, the device may still be in the
	 * transfer. Kept (the channel not lent again) until the line carries
	 * frames again, then the device gets an abort; or freed by the idle
	 * limit. */
	bool orphaned;
	uint8_t from;
	bool engaged; /* the device got a frame of the transfer */
	bool aborted; /* the requester's last frame was an abort */
	/* The requester aborted and is gone: the device may still send frames
	 * of that transfer. Kept (no requester, its channel not lent) until
	 * the device has been quiet for GW_DRAIN_US, so that those frames
	 * never reach the next requester. */
	bool draining;
	/* Its requester's transfer ended well and the requester's line took
	 * the lease for its next one (gw_lend_take_offer): kept bound, moved
	 * to that transfer's node, without a session until the M_OPEN that
	 * follows the M_CLOSE in the ring binds it (gw_relay_open). */
	bool parked;
	/* The M_OPEN of another line's transfer that took this lease while
	 * its M_CLOSE (on its own line's ring) had not come yet: carried out
	 * when the lease parks or ends (gw_relay.c). */
	bool has_pending;
	gw_msg pending;
	uint8_t mux[3]; /* its index, sub-index (from that first frame) */
	uint8_t node;   /* its server, reserved on the lending board */
	/* Answers sent across to the requester (gw_relay.c relay_rx): the
	 * frame they leave on (reply_id 0: never), the requester's last
	 * frame (asked_valid: one answer is due to it), a block transfer (its
	 * sub-blocks break the one-answer-per-request rhythm: never),
	 * pushed_to[from] after the lease's last hand-off there, and the
	 * device's answers that came before the message of the request they
	 * answer (a request sent across): each such message finds its answer
	 * already handed to the session, none due. */
	uint32_t reply_id;
	uint8_t reply_flags;
	bool asked_valid;
	bool block;
	uint8_t asked;
	uint8_t answers_early;
	uint64_t handoff_seq;
	int cli_ch;
	uint32_t sid;
	uint64_t last_us;
	struct gw_line *gl;
};

/* The hop of a routed mailbox SDO transfer (gw_mbx_hop.c). */
enum gw_hop_phase {
	HOP_FREE,
	HOP_ROUTED,     /* resolved; nothing sent yet (the request may wait) */
	HOP_INDICATING, /* lease asked, network indication to the router sent */
	HOP_RELAYING,   /* the transfer's frames go through the lease */
	HOP_REFUSED,    /* ended by the route: the transfer is cancelled */
};

struct gw_mbx_hop {
	uint8_t phase;
	bool unleased;       /* the reservation was refused: no lease to give back */
	bool lease_lost;     /* the target line ended the lease (M_LOST) */
	bool target_aborted; /* the last frame relayed to the target was an abort */
	uint8_t lease_ch;    /* the target line's client channel it holds */
	bool held_valid;
	uint8_t held[8]; /* the transfer's first frame, while indicating */
	uint16_t gen;
	uint16_t net; /* the network asked for */
	uint8_t node; /* the node asked for */
	uint64_t tag; /* the transfer (line_sdo's pending tag) */
	gw_hop hop;   /* line and node (target or router) of the lease */
	struct gw_line *gl;
};

struct gw_line {
	gw *g;
	unsigned idx;
	line *l;
	co_node *node;
	gw_line_params p;
	gw_route_table routes;
	gw_fwd_list fwd;
	gw_pdo_sync lost; /* updates that could not be handed to this line */
	/* This line's TPDOs that other lines may send (published here, read
	 * by them), and per other line i the socket on this line's interface
	 * that line i's thread sends them on (-1: none). */
	gw_fast fast;
	uint32_t sources_gen; /* line_tpdo_sources_generation() fast was built from */
	int peer_fd[GW_LINES_MAX];
	co_frame ignored[GW_FAST_MAX]; /* the fast TPDOs' ids its port leaves out */
	unsigned n_ignored;
	/* Messages this line pushed to each line, handled from each line, and
	 * (published for the senders, once their frames left the transmit
	 * queue) done from each line: a source sends a TPDO of ours itself
	 * only when we have done everything it sent us that woke us
	 * (gw_may_send_fast). */
	uint64_t pushed_to[GW_LINES_MAX];
	uint64_t handled_from[GW_LINES_MAX];
	_Atomic uint64_t done_from[GW_LINES_MAX];
	/* Per target line: pushed_to when the last message that wakes it was
	 * pushed (everything up to there must be done before we send a TPDO
	 * of its), and the target's publication (gw_fast_epoch) the quiet
	 * messages it has not done yet were sent under (gw_may_send_fast). */
	uint64_t woken_mark[GW_LINES_MAX];
	uint32_t quiet_epoch[GW_LINES_MAX];
	uint32_t owed_wake; /* lines to wake at this iteration's end (bit i) */
	bool fwd_dirty;
	uint64_t next_rebuild_us;
	uint64_t next_link_check_us;
	bool carried; /* what the last link check saw (gw_relays_check_link) */
	/* Leases of ours that ended well, per target line, offered on its
	 * lending board's handover (gw_lend_offer) until the target takes
	 * their M_CLOSE: the next transfer of ours that finds its node or
	 * every channel held tries to take one (gw_lease_open). */
	struct gw_closing {
		uint8_t node; /* 0: none, or taken or found gone already */
		uint8_t channel;
	} closing[GW_LINES_MAX][GW_CLOSING_MAX];
	uint8_t closing_next[GW_LINES_MAX];
	uint32_t link_events_seen; /* line_link_events at that look */
	/* What this line lends to routed transfers of other lines (and its
	 * own hops through a router on its bus): read and reserved by them. */
	gw_lend lend;
	struct gw_sess *sess;
	uint8_t n_sess;
	struct gw_relay relay[GW_RELAYS_MAX]; /* by client channel */
	struct gw_mbx_hop hops[GW_HOPS_MAX];
	/* Messages to this line itself (a hop through a router on its own
	 * bus), taken after the rings: never handled inside the call that
	 * sent them. */
	gw_msg self[GW_SELF_SLOTS];
	uint16_t self_head, self_len;
	gw_line_counters c; /* written by this line, read relaxed elsewhere */
};

struct gw {
	unsigned n;
	gw_image *img;
	xring_mesh *mesh;
	struct gw_line line[GW_LINES_MAX];
};

#define GW_COUNT(x) __atomic_fetch_add(&(x), 1, __ATOMIC_RELAXED)

/* gw_hand_off.c: hand m to line `to` (m->from set here); to == gl->idx
 * queues it for this line's next look. 0, or -errno (ring full/closed,
 * own queue full): the caller counts the drop. */
int gw_send_to(struct gw_line *gl, unsigned to, gw_msg *m);
/* gw_send_to for a message line `to` may take at its next wake-up,
 * whatever causes it (xring_push_quiet): one whose frames have all left
 * and that nothing on `to` waits for (gw_fast_quiet_ok), sent under
 * `to`'s publication `epoch` (gw_may_send_fast). */
int gw_send_quiet_to(struct gw_line *gl, unsigned to, gw_msg *m, uint32_t epoch);
/* gw_send_to whose wake-up of `to` waits for the end of this loop
 * iteration (gw_wake_owed, from the line's poll): the updates of one
 * received frame - every object of an RPDO, every forward of a device's
 * TPDO - reach `to` in one wake-up, so it acts on them together (one
 * device RPDO for a frame, not one per object), and `to` is woken once
 * for them, not once per object. */
int gw_send_by_loop_end(struct gw_line *gl, unsigned to, gw_msg *m);
void gw_wake_owed(struct gw_line *gl);
/* May this line send a TPDO of line `to` itself now (`epoch`: to's
 * gw_fast_epoch, read before anything else of its publication)? Only
 * when `to` has done every message of ours that it was woken for, and
 * the quiet ones it has not done yet (fewer than GW_QUIET_WAKE_AT) were
 * sent under the same publication: else a TPDO of an earlier value could
 * still leave from `to` after ours. (any line, about another one) */
bool gw_may_send_fast(const struct gw_line *gl, unsigned to, uint32_t epoch);
/* Would gw_send_across put a frame on `to`'s bus now? (what was decided
 * before it, e.g. an answer record, must agree with it; the answer can
 * only turn from no to yes: done counts only grow) */
bool gw_may_send_across(const struct gw_line *gl, unsigned to, uint64_t handoff_seq);
/* A frame f of a routed transfer for line `to`'s bus, m (M_TO_TARGET or
 * M_TO_REQ, carrying the same 8 bytes) for the owner of the transfer's
 * state there: f leaves from this thread on the socket bound to that
 * interface when nothing this transfer handed to `to` before is still
 * waiting there (*handoff_seq), m telling the owner (GW_SENT_ACROSS,
 * pushed first); else (or f NULL) m is a hand-off and *handoff_seq
 * moves. 0, or the hand-off's -errno (the caller counts the drop). */
int gw_send_across(struct gw_line *gl, unsigned to, gw_msg *m, const co_frame *f,
		   uint64_t *handoff_seq);
/* Publish d as the answer sent across to session sid (before the frame
 * leaves); its sequence number, which the M_TO_REQ carries. (the target
 * line's thread, the record's only writer) */
uint32_t gw_across_publish(struct gw_across *a, uint32_t sid, const uint8_t d[8]);
/* The record's answer for sid if it is newer than *taken (then *taken
 * moves to it); false when there is none. (the entry line) */
bool gw_across_take(const struct gw_across *a, uint32_t sid, uint32_t *taken, uint8_t d[8]);
/* Is record number seq newer than *taken (then *taken moves to it)? The
 * one comparison of the record and the M_TO_REQ that carries its number. */
bool gw_across_newer(uint32_t *taken, uint32_t seq);
/* This line: publish what it handled, if its transmit queue is empty. */
void gw_publish_done(struct gw_line *gl);
/* The oldest message this line sent itself; false when none. */
bool gw_self_take(struct gw_line *gl, gw_msg *out);

/* gw_session.c */
extern const sdo_server_route_ops gw_session_server_hook;
void gw_sessions_init(struct gw_line *gl);
void gw_session_target_frame(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
void gw_session_lost(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
uint64_t gw_sessions_tick(struct gw_line *gl, uint64_t now_us, uint64_t next);

/* gw_relay.c */
/* The requester's side (a session or a hop of line gl): reserve a lease
 * on hop->line's lending board and hand it M_OPEN (reply_id: the frame a
 * session's answers go across on, 0 for a hop, which does not wake the
 * target).
 * 0, or the refusal to answer at once (GW_AB_ROUTE_BUSY: the hand-off is
 * full or closed; the reservation went back). */
uint32_t gw_lease_open(struct gw_line *gl, const gw_hop *hop, uint32_t sid, uint8_t *channel,
		       uint32_t reply_id, uint8_t reply_flags);
/* ... and give it back (M_CLOSE). `settled`: the transfer ended without
 * an abort to the device and the lease was not lost, so the device is
 * idle: the lease is offered to a transfer of ours that follows before
 * the target took the M_CLOSE (remembered in gl->closing). */
void gw_lease_close(struct gw_line *gl, const gw_hop *hop, uint32_t sid, uint8_t channel,
		    bool settled);
/* The target line: publish what it lends (gw_relays_tick does it each
 * look); the gate of its SDO client pool at attach/detach. */
void gw_lend_attach(struct gw_line *gl);
void gw_lend_detach(struct gw_line *gl);
void gw_relay_open(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
void gw_relay_to_target(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
void gw_relay_close(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
/* The frame a lease sends toward its node (cob_req 0 of sdo_client_lease:
 * 600h + node), for the entry line to send it across. */
void gw_relay_request_frame(co_frame *f, uint8_t node, const uint8_t d[8]);
uint64_t gw_relays_tick(struct gw_line *gl, uint64_t now_us, uint64_t next);

/* gw_mbx_hop.c */
uint32_t gw_hop_route(void *ctx, line *l, uint64_t tag, uint16_t net, uint8_t node,
		      line_sdo_route *out);
void gw_hop_end(void *ctx, line *l, uint64_t tag);
void gw_hop_target_frame(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
void gw_hop_lost(struct gw_line *gl, const gw_msg *m, uint64_t now_us);

/* gw_emcy.c */
void gw_emcy_consumed(struct gw_line *gl, const co_ev_emcy *e);
void gw_emcy_send(struct gw_line *gl, const gw_msg *m);

/* gw_pdo.c */
extern const co_od_hooks gw_image_hooks;
void gw_pdo_received(struct gw_line *gl, const gw_msg *m, uint64_t now_us);
/* The fast path of this line's TPDOs (gateway/fast_tpdo.h): open the
 * other lines' sockets on this interface and install the core's gate at
 * attach; republish (with the forwarding list, and in the loop a TPDO
 * was reset in: the core's gate closed it at once); say each loop
 * whether the line takes frames at once. */
int gw_fast_attach(struct gw_line *gl);
void gw_fast_detach(struct gw_line *gl);
void gw_fast_refresh(struct gw_line *gl);
void gw_fast_poll(struct gw_line *gl);
bool gw_pdo_resync_apply(void *ctx, int slot, uint64_t bits);

/* gw_status.c */
void gw_mbx_routes(struct gw_line *gl, const mbx_request *req);

#endif /* COGW_GATEWAY_GW_LINE_H */
