/* SPDX-License-Identifier: MIT */
#include "core/event.h"

const char *co_event_kind_to_string(co_event_kind k)
{
	switch (k) {
	case CO_EV_NONE:
		return "none";
	case CO_EV_OD_WRITTEN:
		return "od-written";
	case CO_EV_SDO_SERVER_DONE:
		return "sdo-server-done";
	case CO_EV_SDO_CLIENT_DONE:
		return "sdo-client-done";
	case CO_EV_SDO_CLIENT_SECOND_ANSWER:
		return "sdo-client-second-answer";
	case CO_EV_RPDO_RECOVERED:
		return "rpdo-recovered";
	case CO_EV_OBJECT_UPDATED:
		return "object-updated";
	case CO_EV_COMM_FAULT:
		return "comm-fault";
	case CO_EV_STORE:
		return "store";
	case CO_EV_RESTORE:
		return "restore";
	case CO_EV_RX_UNHANDLED:
		return "rx-unhandled";
	case CO_EV_TX_FAILED:
		return "tx-failed";
	case CO_EV_NMT_STATE:
		return "nmt-state";
	case CO_EV_BOOTUP:
		return "bootup";
	case CO_EV_HB_STARTED:
		return "hb-started";
	case CO_EV_HB_LOST:
		return "hb-lost";
	case CO_EV_HB_STATE:
		return "hb-state";
	case CO_EV_GUARD_LIFE_LOST:
		return "guard-life-lost";
	case CO_EV_GUARD_LIFE_RESUMED:
		return "guard-life-resumed";
	case CO_EV_GUARD_FAILED:
		return "guard-failed";
	case CO_EV_GUARD_TOGGLE:
		return "guard-toggle";
	case CO_EV_GUARD_RESUMED:
		return "guard-resumed";
	case CO_EV_EMCY_RX:
		return "emcy-rx";
	case CO_EV_SYNC:
		return "sync";
	case CO_EV_TIME:
		return "time";
	case CO_EV_RPDO:
		return "rpdo";
	case CO_EV_RPDO_OBJECT:
		return "rpdo-object";
	case CO_EV_RPDO_TIMEOUT:
		return "rpdo-timeout";
	case CO_EV_RPDO_LENGTH:
		return "rpdo-length";
	case CO_EV_LSS_MASTER_DONE:
		return "lss-master-done";
	case CO_EV_LSS_SLAVE_STATE:
		return "lss-slave-state";
	case CO_EV_LSS_SLAVE_NODE_ID:
		return "lss-slave-node-id";
	case CO_EV_LSS_SLAVE_STORE:
		return "lss-slave-store";
	case CO_EV_LSS_SLAVE_BIT_TIMING:
		return "lss-slave-bit-timing";
	case CO_EV_MGR_STATE:
		return "manager-state";
	case CO_EV_MGR_BOOT:
		return "manager-boot";
	case CO_EV_MGR_NODE:
		return "manager-node";
	case CO_EV_KIND_COUNT:
		break;
	}
	return "?";
}
