/* SPDX-License-Identifier: MIT */
/*
 * lines/socketcan.h - one CAN line's SocketCAN port: a raw CAN socket with
 * error frames, kernel receive timestamps, receive-overflow detection and a
 * bounded transmit queue with back-pressure.
 *
 * Thread: a port belongs to one line thread; nothing here locks or blocks.
 * The socket is non-blocking; the caller waits in epoll on can_port_fd() for
 * EPOLLIN, and for EPOLLOUT while can_port_wants_writable() says so. Frames
 * the kernel cannot take yet stay in the port's transmit queue:
 *  - EAGAIN (socket send buffer full; we shrink SO_SNDBUF so this is what
 *    normally happens): wait for EPOLLOUT, then can_port_flush();
 *  - ENOBUFS (the interface's qdisc queue is full; POLLOUT does not cover
 *    it, it would only spin): retry after can_port_retry_at_us(), with a
 *    backoff that doubles up to 8 ms.
 * When the queue itself is full, can_port_send() refuses (-ENOBUFS) and
 * counts a drop: the caller decides (the core counts it as tx_failed).
 */
#ifndef COGW_LINES_SOCKETCAN_H
#define COGW_LINES_SOCKETCAN_H

#include <stdbool.h>
#include <stdint.h>

#include "core/frame.h"

/* CAN controller state as seen through error frames. */
typedef enum can_bus_state {
	CAN_BUS_ACTIVE = 0, /* error active (normal) */
	CAN_BUS_WARNING,    /* an error counter >= 96 */
	CAN_BUS_PASSIVE,    /* an error counter >= 128 */
	CAN_BUS_OFF,        /* transmit error counter > 255 */
} can_bus_state;

const char *can_bus_state_to_string(can_bus_state s);

/* What an error frame said, decoded (CAN_ERR_* of linux/can/error.h). */
typedef struct can_error_info {
	bool state_changed;
	can_bus_state state;
	bool restarted;          /* controller restarted after bus-off */
	bool controller_problem; /* e.g. controller rx/tx overflow */
	bool rx_overflow;        /* the controller lost received frames */
	bool tx_overflow;        /* ... or frames to transmit */
	bool protocol_violation; /* form/stuff/bit errors */
	bool tx_timeout;
	bool lost_arbitration;
	bool no_ack;
	bool bus_error;
	uint8_t tx_errors; /* counters, if the driver reported them */
	uint8_t rx_errors;
	uint32_t raw_class; /* the error class bits of the frame id */
} can_error_info;

/* Decode an error frame (its can_id with CAN_ERR_FLAG and 8 data bytes).
 * Pure function: no port needed. */
void can_error_decode(uint32_t can_id, const uint8_t data[8], can_bus_state current,
		      can_error_info *out);

typedef struct can_port_config {
	const char *ifname;
	uint32_t bitrate;       /* bit/s, for the bus-load estimate */
	uint16_t tx_queue_len;  /* frames (default 256) */
	uint16_t tx_high_water; /* percent (default 75) */
	uint16_t tx_low_water;  /* percent (default 25) */
	int rcvbuf_bytes;       /* socket receive buffer (default 256 KiB) */
} can_port_config;

typedef struct can_port_stats {
	uint64_t rx_frames;
	uint64_t rx_error_frames;
	uint64_t rx_overflow_drops; /* frames the kernel dropped (SO_RXQ_OVFL) */
	uint64_t rx_invalid;        /* FD or malformed frames ignored */
	uint64_t tx_frames;
	uint64_t tx_queued_max; /* high-water mark of the tx queue */
	uint64_t tx_drops;      /* refused: tx queue full */
	uint64_t tx_eagain;
	uint64_t tx_enobufs;
	uint64_t tx_errors; /* other write errors */
	uint64_t bus_off_count;
	/* bus load: bits on the wire (own + others) in the last full second,
	 * as parts per thousand of the bit rate */
	uint32_t bus_load_permille;
} can_port_stats;

typedef struct can_port can_port;

/* One received item: a frame, or an error frame already decoded. */
typedef struct can_rx_item {
	co_frame frame;
	uint64_t kernel_ts_ns; /* CLOCK_REALTIME of reception, from the kernel */
	bool is_error;
	can_error_info error; /* valid when is_error */
} can_rx_item;

/* Open and bind a raw socket on cfg->ifname. Returns 0 or -errno; on error
 * *errmsg (if not NULL) names the failing step. */
int can_port_open(can_port **out, const can_port_config *cfg, const char **errmsg);
void can_port_close(can_port *p); /* accepts NULL */

int can_port_fd(const can_port *p);

/* Read up to max items without blocking. Returns the count (0 when nothing
 * is pending) or -errno on a socket error. Updates overflow counters and the
 * bus state. now_us feeds the bus-load estimate. */
int can_port_recv(can_port *p, can_rx_item *items, int max, uint64_t now_us);

/* Queue a frame and try to send what is queued. 0 = queued or sent,
 * -ENOBUFS = queue full (dropped, counted), -EINVAL = malformed frame. */
int can_port_send(can_port *p, const co_frame *f, uint64_t now_us);

/* Send as much of the queue as the kernel takes. Returns frames sent. */
int can_port_flush(can_port *p, uint64_t now_us);

size_t can_port_tx_queued(const can_port *p);
/* True while the queue waits for EPOLLOUT (after EAGAIN). */
bool can_port_wants_writable(const can_port *p);
/* Time to retry after ENOBUFS, or UINT64_MAX. */
uint64_t can_port_retry_at_us(const can_port *p);
/* Watermark crossings since the last call: +1 went above high water,
 * -1 went back below low water, 0 none. */
int can_port_take_watermark_event(can_port *p);

can_bus_state can_port_bus_state(const can_port *p);
/* Is the interface administratively up and running (ip link set ... up,
 * carrier present)? A frame sent on a link that is down only fails
 * (ENETDOWN): callers that would wait for an answer ask first. Two ioctls
 * on the port's socket; no blocking. */
bool can_port_link_up(const can_port *p);
const can_port_stats *can_port_get_stats(const can_port *p);

/* The interface of a port, looked up by its name. */
typedef enum can_link_state {
	CAN_LINK_UP = 0,   /* up and running */
	CAN_LINK_DOWN,     /* there, but down or without carrier */
	CAN_LINK_GONE,     /* no interface of that name */
	CAN_LINK_REPLACED, /* one of that name, but not the one the socket is
	                    * bound to (deleted and created again): reopen */
} can_link_state;
/* Two ioctls on the port's socket; no blocking. */
can_link_state can_port_link_state(const can_port *p);
/* The errno (ENETDOWN, ENODEV, ENXIO) a send met since the last call, or
 * 0: a send takes the socket's pending error, which a receive would
 * otherwise have reported. */
int can_port_take_link_error(can_port *p);
/* A new socket on the interface of the port's name (after it was deleted
 * and created again), with the same options and receive filter; the old
 * one is closed, so the caller registers can_port_fd() again wherever it
 * watched the old one. Frames still queued for the old interface are
 * dropped (counted in tx_errors); the bus state starts error-active.
 * 0, or -errno with *errmsg naming the step (the old socket is kept). */
int can_port_reopen(can_port *p, uint64_t now_us, const char **errmsg);

/* Stop receiving data frames with these identifiers (id and the EXT flag
 * of each co_frame; RTR frames still come): frames another socket of this
 * machine sends for this line's own TPDOs, which the line would otherwise
 * receive as it never receives its own. n = 0: receive everything again.
 * At most CAN_PORT_IGNORE_MAX. 0 or -errno. */
#define CAN_PORT_IGNORE_MAX 32u
int can_port_ignore_data(can_port *p, const co_frame *ids, size_t n);

/* ---- transmit-only sockets ---------------------------------------------------
 *
 * A raw socket bound to an interface that never receives (an empty filter):
 * for a thread that sends on a line it does not run (the gateway's PDO
 * forwarding fast path, docs/gateway.md). Non-blocking, nothing is queued:
 * a frame the kernel does not take at once is refused and the caller falls
 * back to another way. The frame reaches the other sockets of the interface
 * (the line's own port among them) as any frame on the bus does.
 * open: the fd or -errno (close() it); send: 0 or -errno (EAGAIN, ENOBUFS,
 * ENETDOWN: the link is down). */
int can_tx_socket_open(const char *ifname);
int can_tx_socket_send(int fd, const co_frame *f);

#endif /* COGW_LINES_SOCKETCAN_H */
