/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_health.h - the wire format of the line's bus health
 * (docs/mailbox.md "Bus health"): the LINE_HEALTH answer and the
 * COMM_FAULT event. Included by mailbox/proto.h, whose enums hold the
 * codes; little-endian, fixed sizes like every mailbox payload.
 */
#ifndef COGW_MAILBOX_PROTO_HEALTH_H
#define COGW_MAILBOX_PROTO_HEALTH_H

#include <stdint.h>

/* What a fault episode is about. 0..5 are the node's communication faults
 * (core/commfault.h, with their CiA 301 EMCY); the transmit-queue pressure
 * is the line's own (no EMCY: no frame is lost yet). */
enum mbx_fault {
	MBX_FAULT_ID_COLLISION = 0, /* another device on our node-ID: 8150h */
	MBX_FAULT_WARNING = 1,      /* controller at the warning limit */
	MBX_FAULT_PASSIVE = 2,      /* error passive: 8120h */
	MBX_FAULT_BUS_OFF = 3,      /* bus-off; 8140h when it ends */
	MBX_FAULT_RX_OVERRUN = 4,   /* received frames lost: 8110h */
	MBX_FAULT_TX_LOST = 5,      /* frames not delivered: 8110h */
	MBX_FAULT_TX_PRESSURE = 6,  /* transmit queue above its high-water mark
	                             * (until back below the low-water mark) */
	MBX_FAULT_LINK_DOWN = 7,    /* the interface is down or deleted (until it
	                             * is up and running again) */
	MBX_FAULT_COUNT = 8
};

/* "id-collision", "warning", "passive", "bus-off", "rx-overrun",
 * "tx-lost", "tx-pressure", "link-down"; "?" otherwise. Inline: the header is the
 * whole of this part of the protocol. */
static inline const char *mbx_fault_to_string(unsigned fault)
{
	static const char *const names[MBX_FAULT_COUNT] = {
		"id-collision", "warning", "passive",     "bus-off",
		"rx-overrun",   "tx-lost", "tx-pressure", "link-down",
	};
	return fault < MBX_FAULT_COUNT ? names[fault] : "?";
}

typedef struct mbx_fault_counters {
	uint8_t active; /* an episode runs */
	uint8_t info;   /* id-collision: the state byte last heard */
	uint16_t pad;
	uint32_t episodes;    /* begun since the last reset */
	uint32_t occurrences; /* frames or reports since the last reset */
	uint32_t age_ms;      /* since the last occurrence (saturates;
	                       * 0xFFFFFFFF = none since the start) */
} mbx_fault_counters;

/* LINE_HEALTH answer. */
typedef struct mbx_line_health {
	uint8_t can_state; /* enum mbx_can_state */
	uint8_t n_faults;  /* MBX_FAULT_COUNT */
	uint8_t tec;       /* transmit / receive error counters of the last */
	uint8_t rec;       /* error frame that carried them */
	uint32_t restarts; /* controller restarts after bus-off */
	uint32_t id_collision_quiet_ms;
	uint32_t lost_quiet_ms;
	uint64_t rx_overflow_drops; /* frames the kernel dropped (socket) */
	uint64_t tx_dropped;        /* refused: transmit queue full */
	uint64_t tx_errors;         /* the kernel refused them (e.g. link down) */
	uint64_t tx_queued_max;     /* high-water mark of the transmit queue */
	uint32_t reopens;           /* new sockets on an interface created again */
	uint32_t last_outage_ms;    /* how long the interface was down last time */
	mbx_fault_counters fault[MBX_FAULT_COUNT];
} mbx_line_health;

/* MBX_EV_COMM_FAULT: an episode began (active = 1) or ended (0). */
typedef struct mbx_ev_comm_fault {
	uint8_t fault; /* enum mbx_fault */
	uint8_t active;
	uint8_t info;      /* id-collision: the state byte heard */
	uint8_t can_state; /* enum mbx_can_state now */
	uint32_t episodes;
	uint32_t occurrences;
} mbx_ev_comm_fault;

#endif /* COGW_MAILBOX_PROTO_HEALTH_H */
