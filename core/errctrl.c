/* SPDX-License-Identifier: MIT */
/*
 * Error control shared by heartbeat and guarding (core/errctrl.h).
 *
 * Both protocols end in the same error behaviour (EMCY 8130h, 1029h:1) and
 * 8130h may only be cleared when neither of them still sees a loss. Before
 * this module, each asked the other ("any loss left on your side?", "is
 * this node yours?"), a call cycle; now each reports here and reads from
 * here.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/emcy.h"
#include "core/errctrl.h"
#include "core/nmt.h"

#define ERRCTRL_NODES 128u /* index = node-id 1..127 */

struct co_errctrl {
	bool lost[CO_ERRCTRL_SRC_COUNT];
	bool guarded[ERRCTRL_NODES];
};

void co_errctrl_emit(co_node *node, co_event_kind kind, uint8_t remote, uint8_t state, uint8_t prev,
		     bool guarded, uint16_t time_ms)
{
	co_event ev = { .kind = kind };

	ev.u.errctrl.node = remote;
	ev.u.errctrl.state = state;
	ev.u.errctrl.prev = prev;
	ev.u.errctrl.guarded = guarded;
	ev.u.errctrl.time_ms = time_ms;
	co_node_emit(node, &ev);
}

void co_errctrl_comm_lost(co_node *node, co_errctrl_source src, uint8_t msef_node, uint64_t now_us)
{
	uint8_t msef[5] = { msef_node, 0, 0, 0, 0 };

	if (node->errctrl)
		node->errctrl->lost[src] = true;
	/* CiA 301: an error-control event is a communication error: EMCY
	 * first (while the state still allows it), then 1029h:1. */
	(void)co_emcy_send(node, CO_EMCY_LIFE_GUARD, CO_EMCY_REG_COMM, msef, now_us);
	(void)co_nmt_comm_error(node, now_us);
}

void co_errctrl_loss_update(co_node *node, co_errctrl_source src, bool lost, uint64_t now_us)
{
	struct co_errctrl *ec = node->errctrl;

	if (!ec)
		return;
	ec->lost[src] = lost;
	for (unsigned s = 0; s < CO_ERRCTRL_SRC_COUNT; s++)
		if (ec->lost[s])
			return;
	(void)co_emcy_clear(node, CO_EMCY_LIFE_GUARD, now_us);
}

void co_errctrl_guarded_set(co_node *node, uint8_t remote, bool on)
{
	if (node->errctrl && remote < ERRCTRL_NODES)
		node->errctrl->guarded[remote] = on;
}

bool co_errctrl_guarded(const co_node *node, uint8_t remote)
{
	return node->errctrl && remote < ERRCTRL_NODES && node->errctrl->guarded[remote];
}

/* ---- service ------------------------------------------------------------- */

static int errctrl_init(co_node *node)
{
	node->errctrl = calloc(1, sizeof(*node->errctrl));
	return node->errctrl ? 0 : -ENOMEM;
}

static void errctrl_fini(co_node *node)
{
	free(node->errctrl);
	node->errctrl = NULL;
}

const co_service co_svc_errctrl = {
	.name = "errctrl",
	.init = errctrl_init,
	.fini = errctrl_fini,
};
