/* SPDX-License-Identifier: MIT */
#include "core/event.h"

static const char *const kind_names[CO_EV_KIND_COUNT] = {
	[CO_EV_NONE] = "none",
	[CO_EV_OD_WRITTEN] = "od-written",
	[CO_EV_SDO_SERVER_DONE] = "sdo-server-done",
	[CO_EV_SDO_CLIENT_DONE] = "sdo-client-done",
	[CO_EV_SDO_CLIENT_SECOND_ANSWER] = "sdo-client-second-answer",
	[CO_EV_RPDO_RECOVERED] = "rpdo-recovered",
	[CO_EV_OBJECT_UPDATED] = "object-updated",
	[CO_EV_COMM_FAULT] = "comm-fault",
	[CO_EV_STORE] = "store",
	[CO_EV_RESTORE] = "restore",
	[CO_EV_RX_UNHANDLED] = "rx-unhandled",
	[CO_EV_TX_FAILED] = "tx-failed",
	[CO_EV_NMT_STATE] = "nmt-state",
	[CO_EV_BOOTUP] = "bootup",
	[CO_EV_HB_STARTED] = "hb-started",
	[CO_EV_HB_LOST] = "hb-lost",
	[CO_EV_HB_STATE] = "hb-state",
	[CO_EV_GUARD_LIFE_LOST] = "guard-life-lost",
	[CO_EV_GUARD_LIFE_RESUMED] = "guard-life-resumed",
	[CO_EV_GUARD_FAILED] = "guard-failed",
	[CO_EV_GUARD_TOGGLE] = "guard-toggle",
	[CO_EV_GUARD_RESUMED] = "guard-resumed",
	[CO_EV_EMCY_RX] = "emcy-rx",
	[CO_EV_SYNC] = "sync",
	[CO_EV_TIME] = "time",
	[CO_EV_RPDO] = "rpdo",
	[CO_EV_RPDO_OBJECT] = "rpdo-object",
	[CO_EV_RPDO_TIMEOUT] = "rpdo-timeout",
	[CO_EV_RPDO_LENGTH] = "rpdo-length",
	[CO_EV_LSS_MASTER_DONE] = "lss-master-done",
	[CO_EV_LSS_SLAVE_STATE] = "lss-slave-state",
	[CO_EV_LSS_SLAVE_NODE_ID] = "lss-slave-node-id",
	[CO_EV_LSS_SLAVE_STORE] = "lss-slave-store",
	[CO_EV_LSS_SLAVE_BIT_TIMING] = "lss-slave-bit-timing",
	[CO_EV_MGR_STATE] = "manager-state",
	[CO_EV_MGR_BOOT] = "manager-boot",
	[CO_EV_MGR_NODE] = "manager-node",
};

const char *co_event_kind_to_string(co_event_kind k)
{
	if ((unsigned)k >= CO_EV_KIND_COUNT || !kind_names[k])
		return "?";
	return kind_names[k];
}
