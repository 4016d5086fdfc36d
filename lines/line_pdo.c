/* SPDX-License-Identifier: MIT */
/*
 * lines/line_pdo.c - supervision of the RPDOs of the line's own node
 * (CiA 301 §7.5.2.35 deadline, §7.5.2.36 length; the episodes and their
 * EMCYs are core/pdo.c's): the PDO_FAULT events and the RPDO_STATUS
 * command behind `cogwctl diag`.
 *
 * One event per episode, not per bad frame: a device sending a short RPDO
 * every millisecond must not flood every subscriber (the frames are
 * counted, RPDO_STATUS tells how many).
 */
#include "lines/line_internal.h"

#include <inttypes.h>
#include <string.h>

#include "core/emcy.h"
#include "core/pdo.h"
#include "lines/log.h"

/* The bits of both enums are the same, CO_PDO_FAULT_* is the core's. */
_Static_assert((unsigned)MBX_RPDO_FAULT_TIMEOUT == (unsigned)CO_PDO_FAULT_TIMEOUT &&
		       (unsigned)MBX_RPDO_FAULT_SHORT == (unsigned)CO_PDO_FAULT_SHORT &&
		       (unsigned)MBX_RPDO_FAULT_LONG == (unsigned)CO_PDO_FAULT_LONG,
	       "one fault bit set");

static uint32_t wire_cob_id(const co_ev_pdo *p)
{
	return p->cob_id | ((p->flags & CO_FRAME_EXT) ? CO_PDO_COB_EXT : 0);
}

static uint16_t fault_emcy_code(uint8_t fault)
{
	switch (fault) {
	case CO_PDO_FAULT_TIMEOUT:
		return CO_EMCY_RPDO_TIMEOUT;
	case CO_PDO_FAULT_SHORT:
		return CO_EMCY_PDO_LENGTH;
	case CO_PDO_FAULT_LONG:
		return CO_EMCY_PDO_LENGTH_HIGH;
	}
	return 0;
}

void line_publish_rpdo_fault(line *l, const co_event *ev)
{
	const co_ev_pdo *p = &ev->u.pdo;
	bool began = ev->kind != CO_EV_RPDO_RECOVERED;
	mbx_ev_rpdo_fault m = {
		.ts_us = ev->now_us,
		.cob_id = wire_cob_id(p),
		.pdo = p->nr,
		.fault = p->fault,
		.len = p->len,
		.mapped_len = p->mapped_len,
		.event_ms = p->event_ms,
		.emcy = began ? fault_emcy_code(p->fault) : 0,
	};
	if (began) {
		unsigned k = (unsigned)__builtin_ctz(p->fault);
		if (k < CO_PDO_FAULT_KINDS)
			l->rpdo_episodes[k]++;
		if (p->fault == CO_PDO_FAULT_TIMEOUT)
			cogw_log(COGW_LOG_WARNING,
				 "line %s: RPDO %u (COB-ID %03" PRIX32
				 "h) missed its %u ms deadline",
				 l->name, p->nr, p->cob_id, p->event_ms);
		else
			cogw_log(COGW_LOG_WARNING,
				 "line %s: RPDO %u (COB-ID %03" PRIX32
				 "h) of %u bytes, %u mapped: %s",
				 l->name, p->nr, p->cob_id, p->len, p->mapped_len,
				 p->fault == CO_PDO_FAULT_SHORT ? "not processed"
								: "leading bytes used");
	}
	mbx_server_publish(l->mbx, began ? MBX_EV_RPDO_FAULT : MBX_EV_RPDO_RECOVERED, 0, &m,
			   sizeof m);
}

void line_rpdo_status(line *l, const mbx_request *req)
{
	/* the answer is built on the line thread's stack: bounded by the
	 * RPDOs a node can have */
	struct {
		mbx_rpdo_status head;
		mbx_rpdo_fault_entry rows[CO_PDO_MAX];
	} a;
	const co_pdo_stats *st = co_pdo_get_stats(l->node);
	uint16_t n_rx = co_pdo_count(l->node, CO_PDO_RX);
	memset(&a.head, 0, sizeof a.head);
	a.head.rx = st->rx;
	a.head.rx_length = st->rx_length;
	a.head.rx_timeout = st->rx_timeout;
	a.head.rx_late = st->rx_late;
	a.head.od_refused = st->od_refused;
	for (unsigned k = 0; k < CO_PDO_FAULT_KINDS; k++)
		a.head.episodes[k] = l->rpdo_episodes[k];
	a.head.rpdos = n_rx;
	uint16_t n = 0;
	for (uint16_t nr = 1; nr <= CO_PDO_MAX && n < n_rx; nr++) {
		co_pdo_rpdo_state s;
		if (co_pdo_rpdo_state_get(l->node, nr, &s) < 0 || !s.faults)
			continue;
		a.rows[n++] = (mbx_rpdo_fault_entry){ .cob_id = s.cob_id & ~CO_PDO_COB_INVALID,
						      .pdo = nr,
						      .faults = s.faults,
						      .mapped_len = s.mapped_len,
						      .event_ms = s.event_ms };
	}
	a.head.n = n;
	line_answer(l, &req->reply, 0, 0, &a, sizeof a.head + n * sizeof a.rows[0]);
}
