/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/support/sdo_req.h - an SDO requester on a raw CAN
 * socket: the core's own SDO client in a node of its own, fed with the
 * socket's frames by the calling thread. The gateway test and benchmark
 * use it as a service tool plugged into a line (after a hand-made network
 * indication, or directly), the same code both ways.
 */
#ifndef COGW_TESTS_SDO_REQ_H
#define COGW_TESTS_SDO_REQ_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/sdo_client.h"

typedef struct sdo_req {
	int fd; /* the caller's raw socket: frames go out and come in here */
	co_od *od;
	co_node *node;
	bool done;
	co_ev_sdo_cli res; /* the last transfer's outcome */
} sdo_req;

/* A node node_id with one SDO client (per-frame timeout timeout_ms) on fd.
 * 0 or -errno. */
int sdo_req_init(sdo_req *q, int fd, uint8_t node_id, uint32_t timeout_ms);
void sdo_req_fini(sdo_req *q); /* accepts a zeroed or finished one */
/* Submit r on the client and feed it fd's frames until it is done or
 * timeout_ms passed: 0 = done (outcome in q->res), -ETIMEDOUT, or the
 * submit's error. Frames already waiting in fd count as answers: the
 * caller empties a socket that heard other traffic on the same COB-IDs
 * (another client of the same server) before it starts a transfer. */
int sdo_req_transfer(sdo_req *q, const sdo_client_req *r, int timeout_ms);
/* The same in steps, to run several requesters from one thread: submit,
 * then step each (wait up to wait_ms for a frame, feed every frame
 * waiting, and run its timers) until q->done. */
int sdo_req_submit(sdo_req *q, const sdo_client_req *r);
void sdo_req_step(sdo_req *q, int wait_ms);
/* The CLOCK_MONOTONIC µs the requester runs on. */
uint64_t sdo_req_now_us(void);

#endif /* COGW_TESTS_SDO_REQ_H */
