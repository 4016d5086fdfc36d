/* SPDX-License-Identifier: MIT */
/*
 * core/manager.c - life cycle and time of the CiA 302-2 manager of one
 * line; the design and the files are described in core/manager_int.h.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/manager_int.h"
#include "core/nmt.h"
#include "core/sdo_client.h"

uint64_t co_manager_next_deadline_us(const co_manager *m)
{
	uint64_t t = m->autostart_pending ? 0 : CO_NO_DEADLINE;
	if (m->timer_us < t)
		t = m->timer_us;
	if (m->scan_us < t)
		t = m->scan_us;
	for (unsigned id = 1; id <= 127; id++)
		if (m->s[id].timer_us < t)
			t = m->s[id].timer_us;
	return t;
}

uint64_t co_manager_tick(co_manager *m, uint64_t now_us)
{
	mgr_enter(m, now_us);
	if (m->autostart_pending) {
		m->autostart_pending = false;
		co_fsm_goto(&m->fsm, is_master(m) ? CO_MGR_RESETTING : CO_MGR_SLAVE, now_us);
	}
	if (m->timer_us <= now_us) {
		m->timer_us = CO_NO_DEADLINE;
		co_fsm_timeout(&m->fsm, now_us);
	}
	for (unsigned id = 1; id <= 127; id++) {
		struct mgr_slave *s = &m->s[id];
		if (s->timer_us <= now_us) {
			s->timer_us = CO_NO_DEADLINE;
			co_fsm_timeout(&s->fsm, now_us);
		}
	}
	if (m->cfg.scan_ms && m->scan_us <= now_us) {
		mgr_scan(m, now_us);
		m->scan_us = now_us + (uint64_t)m->cfg.scan_ms * 1000u;
	}
	mgr_after(m, now_us);
	return co_manager_next_deadline_us(m);
}

int co_manager_create(co_manager **out, co_node *node, const co_manager_config *cfg)
{
	co_manager *m;
	uint8_t n_cli = sdo_client_channel_count(node);

	*out = NULL;
	if (!cfg || !n_cli)
		return -EINVAL;
	m = calloc(1, sizeof(*m));
	if (!m)
		return -ENOMEM;
	m->node = node;
	m->od = co_node_od(node);
	m->cfg = *cfg;
	m->own_id = co_node_id(node);
	m->n_slots = m->cfg.max_parallel && m->cfg.max_parallel < n_cli ? m->cfg.max_parallel
									: n_cli;
	if (!m->cfg.sdo_timeout_ms)
		m->cfg.sdo_timeout_ms = 500;
	if (!m->cfg.reset_wait_ms)
		m->cfg.reset_wait_ms = 1000;
	if (!m->cfg.retry_ms)
		m->cfg.retry_ms = 1000;
	m->timer_us = CO_NO_DEADLINE;
	m->scan_us = m->cfg.scan_ms ? 0 : CO_NO_DEADLINE;
	m->autostart_pending = !m->cfg.no_autostart;
	co_fsm_init(&m->fsm, &mgr_net_def, m, CO_MGR_SLAVE);
	for (unsigned id = 0; id < 128; id++) {
		struct mgr_slave *s = &m->s[id];
		s->m = m;
		s->id = (uint8_t)id;
		s->timer_us = CO_NO_DEADLINE;
		s->last_state = STATE_UNKNOWN;
		s->expected_state = STATE_UNKNOWN;
		s->target_state = CO_NMT_OPERATIONAL;
		co_fsm_init(&s->fsm, &mgr_boot_def, s, BS_IDLE);
	}
	for (unsigned i = 0; i < 3; i++)
		m->rx[i] = -1;
	if (m->own_id >= 1 && m->own_id <= 127) {
		/* frames a device on our own ID would send: heartbeat/boot-up,
		 * EMCY, SDO server answers (we never receive our own) */
		static const uint32_t base[3] = { 0x700, 0x080, 0x580 };
		for (unsigned i = 0; i < 3; i++)
			m->rx[i] = co_rx_register(node, base[i] + m->own_id, 0, mgr_own_id_rx, m);
	}
	mgr_od_hooks(m, true);
	co_nmt_set_rx_filter(node, mgr_nmt_rx_filter, m);
	*out = m;
	return 0;
}

void co_manager_destroy(co_manager *m)
{
	if (!m)
		return;
	/* requests still out would confirm into freed memory */
	m->destroying = true;
	for (unsigned id = 1; id <= 127; id++)
		if (m->s[id].sdo_pending)
			(void)sdo_client_cancel_tag(m->node, m->s[id].tag, SDO_AB_GENERAL,
						    m->node->now_us);
	co_nmt_set_rx_filter(m->node, NULL, NULL);
	mgr_od_hooks(m, false);
	for (unsigned i = 0; i < 3; i++)
		if (m->rx[i] >= 0)
			(void)co_rx_unregister(m->node, m->rx[i]);
	free(m);
}
