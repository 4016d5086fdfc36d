/* SPDX-License-Identifier: MIT */
/*
 * core/appwd.c - the application watchdog's table and the reactions the
 * line runs on its own node (core/appwd.h).
 *
 * The table is small (CO_APPWD_MAX) and walked linearly: it is looked at
 * once per loop iteration for its deadline and once per keep-alive.
 */
#include "core/appwd.h"

#include <errno.h>
#include <string.h>

#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "core/od.h"
#include "core/pdo.h"

bool co_appwd_reactions_valid(uint32_t reactions)
{
	uint32_t nmt = reactions & CO_APPWD_NMT_MASK;

	if (!reactions || (reactions & ~CO_APPWD_ALL))
		return false;
	return (nmt & (nmt - 1u)) == 0; /* at most one NMT reaction */
}

uint8_t co_appwd_nmt_cs(uint32_t reactions)
{
	if (reactions & CO_APPWD_NMT_PREOP)
		return CO_NMT_CS_ENTER_PREOP;
	if (reactions & CO_APPWD_NMT_STOP)
		return CO_NMT_CS_STOP;
	if (reactions & CO_APPWD_NMT_RESET_COMM)
		return CO_NMT_CS_RESET_COMM;
	if (reactions & CO_APPWD_NMT_RESET_NODE)
		return CO_NMT_CS_RESET_NODE;
	return 0;
}

const char *co_appwd_state_to_string(co_appwd_state s)
{
	switch (s) {
	case CO_APPWD_FREE:
		return "free";
	case CO_APPWD_DECLARED:
		return "declared";
	case CO_APPWD_ARMED:
		return "armed";
	case CO_APPWD_TRIPPED:
		return "tripped";
	}
	return "?";
}

void co_appwd_init(co_appwd *wd)
{
	memset(wd, 0, sizeof *wd);
}

static co_appwd_entry *find(co_appwd *wd, uint32_t owner)
{
	for (unsigned i = 0; i < CO_APPWD_MAX; i++)
		if (wd->e[i].state != CO_APPWD_FREE && wd->e[i].owner == owner && !wd->e[i].gone)
			return &wd->e[i];
	return NULL;
}

const co_appwd_entry *co_appwd_find(const co_appwd *wd, uint32_t owner)
{
	return find((co_appwd *)wd, owner);
}

static co_appwd_entry *find_free(co_appwd *wd)
{
	for (unsigned i = 0; i < CO_APPWD_MAX; i++)
		if (wd->e[i].state == CO_APPWD_FREE)
			return &wd->e[i];
	return NULL;
}

int co_appwd_declare(co_appwd *wd, uint32_t owner, uint32_t pid, uint32_t interval_ms,
		     uint32_t reactions)
{
	co_appwd_entry *e = find(wd, owner);

	if (!interval_ms) {
		if (!e)
			return -ENOENT;
		memset(e, 0, sizeof *e);
		return 0;
	}
	if (interval_ms < CO_APPWD_INTERVAL_MIN_MS || interval_ms > CO_APPWD_INTERVAL_MAX_MS ||
	    !co_appwd_reactions_valid(reactions)) {
		wd->stats.refused++;
		return -EINVAL;
	}
	if (!e && !(e = find_free(wd))) {
		wd->stats.refused++;
		return -ENOSPC;
	}
	*e = (co_appwd_entry){ .state = CO_APPWD_DECLARED,
			       .owner = owner,
			       .pid = pid,
			       .interval_ms = interval_ms,
			       .reactions = reactions };
	wd->stats.declared++;
	return 0;
}

int co_appwd_keepalive(co_appwd *wd, uint32_t owner, uint64_t now_us)
{
	co_appwd_entry *e = find(wd, owner);

	if (!e)
		return -ENOENT;
	if (e->state == CO_APPWD_TRIPPED) {
		wd->stats.late_keepalives++;
		return -ESTALE;
	}
	e->state = CO_APPWD_ARMED;
	e->deadline_us = now_us + (uint64_t)e->interval_ms * 1000u;
	e->keepalives++;
	wd->stats.keepalives++;
	return 0;
}

void co_appwd_owner_gone(co_appwd *wd, uint32_t owner)
{
	co_appwd_entry *e = find(wd, owner);

	if (!e)
		return;
	if (e->state == CO_APPWD_ARMED)
		e->gone = true;
	else
		memset(e, 0, sizeof *e);
}

size_t co_appwd_poll(co_appwd *wd, uint64_t now_us, co_appwd_entry *fired, size_t cap)
{
	size_t n = 0;

	for (unsigned i = 0; i < CO_APPWD_MAX && n < cap; i++) {
		co_appwd_entry *e = &wd->e[i];
		if (e->state != CO_APPWD_ARMED || now_us < e->deadline_us)
			continue;
		e->state = CO_APPWD_TRIPPED;
		wd->stats.trips++;
		fired[n++] = *e;
		if (e->gone) /* nobody left to declare again */
			memset(e, 0, sizeof *e);
	}
	return n;
}

uint64_t co_appwd_next_deadline(const co_appwd *wd)
{
	uint64_t next = CO_NO_DEADLINE;

	for (unsigned i = 0; i < CO_APPWD_MAX; i++)
		if (wd->e[i].state == CO_APPWD_ARMED && wd->e[i].deadline_us < next)
			next = wd->e[i].deadline_us;
	return next;
}

bool co_appwd_any_tripped(const co_appwd *wd)
{
	for (unsigned i = 0; i < CO_APPWD_MAX; i++)
		if (wd->e[i].state == CO_APPWD_TRIPPED)
			return true;
	return false;
}

/* ---- reactions ----------------------------------------------------------- */

static bool safe_output_write(co_od *od, const co_safe_output *o)
{
	co_od_entry *e = co_od_find(od, o->index, o->sub);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL, .data = o->value, .size = o->len };

	if (!e || co_od_check_value(e, o->value, o->len))
		return false;
	co_od_commit(e, o->value, o->len, &a);
	return true;
}

size_t co_appwd_safe_outputs_apply(co_node *node, const co_safe_output *outs, size_t n,
				   uint64_t now_us)
{
	co_od *od = co_node_od(node);
	size_t written = 0;

	for (size_t i = 0; i < n; i++)
		written += safe_output_write(od, &outs[i]);
	/* all values first, then the PDOs: the first frame of a TPDO mapping
	 * two safe outputs already carries both (it is triggered once per
	 * object it maps; within its inhibit time the second waits) */
	for (size_t i = 0; i < n; i++)
		(void)co_pdo_object_changed(node, outs[i].index, outs[i].sub, now_us);
	return written;
}

static bool hb_stop(co_node *node, co_appwd_effects *fx, uint64_t now_us)
{
	uint16_t ms = 0;

	if (co_od_get_u16(co_node_od(node), 0x1017, 0, &ms) < 0)
		return false;
	if (!fx->hb_stopped)
		fx->hb_saved_ms = ms;
	if (co_hb_producer_set(node, 0, now_us) < 0)
		return false;
	fx->hb_stopped = true;
	return true;
}

/* -ENOSPC: sent, only not clearable on its own (core/emcy.h) */
static bool emcy_sent(int rc)
{
	return rc == 0 || rc == -ENOSPC;
}

uint32_t co_appwd_react(co_node *node, uint32_t reactions, const co_safe_output *outs,
			size_t n_outs, co_appwd_effects *fx, uint64_t now_us)
{
	uint32_t done = 0;

	if ((reactions & CO_APPWD_SAFE_OUTPUTS) && n_outs) {
		(void)co_appwd_safe_outputs_apply(node, outs, n_outs, now_us);
		done |= CO_APPWD_SAFE_OUTPUTS;
	}
	/* GENERIC is added by the EMCY service: 81h */
	if ((reactions & CO_APPWD_EMCY) &&
	    emcy_sent(co_emcy_send(node, CO_APPWD_EMCY_CODE, CO_EMCY_REG_MANUF, NULL, now_us))) {
		fx->emcy = true;
		done |= CO_APPWD_EMCY;
	}
	if ((reactions & CO_APPWD_HB_STOP) && hb_stop(node, fx, now_us))
		done |= CO_APPWD_HB_STOP;
	return done;
}

void co_appwd_acknowledge(co_node *node, co_appwd_effects *fx, uint64_t now_us)
{
	if (fx->emcy && co_emcy_is_active(node, CO_APPWD_EMCY_CODE))
		(void)co_emcy_clear(node, CO_APPWD_EMCY_CODE, now_us);
	if (fx->hb_stopped)
		(void)co_hb_producer_set(node, fx->hb_saved_ms, now_us);
	*fx = (co_appwd_effects){ 0 };
}
