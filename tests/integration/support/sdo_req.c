/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/support/sdo_req.c - an SDO requester on a raw CAN
 * socket (sdo_req.h).
 */
#include "tests/integration/support/sdo_req.h"

#include <errno.h>
#include <linux/can.h>
#include <poll.h>
#include <string.h>
#include <unistd.h>
#include <sys/socket.h>

#include "lines/line.h"
#include "tests/integration/support/proc.h"

uint64_t sdo_req_now_us(void)
{
	return line_now_us(); /* the daemon's own clock: CLOCK_MONOTONIC µs */
}

static int req_send(void *ctx, const co_frame *f)
{
	sdo_req *q = ctx;

	/* A full socket queue (ENOBUFS) clears within microseconds on vcan:
	 * retry rather than lose a frame of the transfer. */
	for (int tries = 0; tries < 100000; tries++)
		if (can_send_std(q->fd, f->id, f->data, f->len) == 0)
			return 0;
		else
			sleep_ms(0);
	return -EIO;
}

static void req_event(void *ctx, const co_event *ev)
{
	sdo_req *q = ctx;

	if (ev->kind == CO_EV_SDO_CLIENT_DONE) {
		q->res = ev->u.sdo_cli;
		q->done = true;
	}
}

int sdo_req_init(sdo_req *q, int fd, uint8_t node_id, uint32_t timeout_ms)
{
	co_node_config c = { .node_id = node_id,
			     .sdo_client_count = 1,
			     .sdo_client_timeout_ms = timeout_ms,
			     .send = req_send,
			     .send_ctx = q,
			     .event = req_event,
			     .event_ctx = q };
	int rc;

	memset(q, 0, sizeof *q);
	q->fd = fd;
	if ((rc = co_od_create(&q->od, 16)))
		return rc;
	c.od = q->od;
	return co_node_create(&q->node, &c);
}

void sdo_req_fini(sdo_req *q)
{
	co_node_destroy(q->node);
	co_od_destroy(q->od);
	q->node = NULL;
	q->od = NULL;
}

int sdo_req_submit(sdo_req *q, const sdo_client_req *r)
{
	q->done = false;
	return sdo_client_submit(q->node, 0, r, sdo_req_now_us());
}

void sdo_req_step(sdo_req *q, int wait_ms)
{
	struct pollfd p = { .fd = q->fd, .events = POLLIN };
	uint64_t dl = co_node_next_deadline_us(q->node), t = sdo_req_now_us();

	if (dl != CO_NO_DEADLINE && dl > t && (dl - t) / 1000u < (uint64_t)wait_ms)
		wait_ms = (int)((dl - t) / 1000u) + 1;
	/* Every frame waiting, not one: a socket shared with other traffic
	 * (another requester's frames and answers on the same bus) would
	 * otherwise fall behind by a frame at each of that requester's turns,
	 * until the kernel drops this requester's own answer at the full
	 * receive queue. */
	if (poll(&p, 1, wait_ms) > 0) {
		struct can_frame cf;
		while (recv(q->fd, &cf, sizeof cf, MSG_DONTWAIT) == (ssize_t)sizeof cf) {
			co_frame f;
			if (cf.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG))
				continue;
			co_frame_init(&f, cf.can_id, cf.len);
			memcpy(f.data, cf.data, 8);
			co_node_recv(q->node, &f, sdo_req_now_us());
		}
	}
	co_node_tick(q->node, sdo_req_now_us());
}

int sdo_req_transfer(sdo_req *q, const sdo_client_req *r, int timeout_ms)
{
	uint64_t until = sdo_req_now_us() + (uint64_t)timeout_ms * 1000u;
	int rc;

	if ((rc = sdo_req_submit(q, r)))
		return rc;
	while (!q->done && sdo_req_now_us() < until)
		sdo_req_step(q, 5);
	return q->done ? 0 : -ETIMEDOUT;
}
