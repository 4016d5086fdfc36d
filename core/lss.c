/* SPDX-License-Identifier: MIT */
/*
 * LSS (CiA 305): names for the shared constants and the bit timing table,
 * used by both ends. The protocol lives in lss_master.c and lss_slave.c,
 * the core service that hosts them in lss_service.c (a separate file, so
 * that the ends call this one and it calls none of them).
 */
#include "core/lss.h"

const char *lss_cs_to_string(uint8_t cs)
{
	switch ((lss_cs)cs) {
	case LSS_CS_SWITCH_GLOBAL:
		return "switch-global";
	case LSS_CS_CONFIG_NODE_ID:
		return "config-node-id";
	case LSS_CS_CONFIG_BIT_TIMING:
		return "config-bit-timing";
	case LSS_CS_ACTIVATE_BIT_TIMING:
		return "activate-bit-timing";
	case LSS_CS_STORE:
		return "store";
	case LSS_CS_SWITCH_SEL_VENDOR:
		return "switch-selective-vendor";
	case LSS_CS_SWITCH_SEL_PRODUCT:
		return "switch-selective-product";
	case LSS_CS_SWITCH_SEL_REVISION:
		return "switch-selective-revision";
	case LSS_CS_SWITCH_SEL_SERIAL:
		return "switch-selective-serial";
	case LSS_CS_SWITCH_SEL_RESPONSE:
		return "switch-selective-response";
	case LSS_CS_IDENT_VENDOR:
		return "identify-vendor";
	case LSS_CS_IDENT_PRODUCT:
		return "identify-product";
	case LSS_CS_IDENT_REVISION_LOW:
		return "identify-revision-low";
	case LSS_CS_IDENT_REVISION_HIGH:
		return "identify-revision-high";
	case LSS_CS_IDENT_SERIAL_LOW:
		return "identify-serial-low";
	case LSS_CS_IDENT_SERIAL_HIGH:
		return "identify-serial-high";
	case LSS_CS_IDENT_NON_CONFIGURED:
		return "identify-non-configured";
	case LSS_CS_IDENT_SLAVE:
		return "identify-slave";
	case LSS_CS_IDENT_NON_CONFIGURED_SLAVE:
		return "identify-non-configured-slave";
	case LSS_CS_FASTSCAN:
		return "fastscan";
	case LSS_CS_INQUIRE_VENDOR:
		return "inquire-vendor";
	case LSS_CS_INQUIRE_PRODUCT:
		return "inquire-product";
	case LSS_CS_INQUIRE_REVISION:
		return "inquire-revision";
	case LSS_CS_INQUIRE_SERIAL:
		return "inquire-serial";
	case LSS_CS_INQUIRE_NODE_ID:
		return "inquire-node-id";
	}
	return "?";
}

const char *lss_state_to_string(lss_state s)
{
	switch (s) {
	case LSS_STATE_WAITING:
		return "waiting";
	case LSS_STATE_CONFIGURATION:
		return "configuration";
	}
	return "?";
}

const char *lss_error_to_string(uint8_t cs, uint8_t code)
{
	if (code == LSS_EC_OK)
		return "success";
	if (code == LSS_EC_SPECIFIC)
		return "implementation specific error";
	switch (cs) {
	case LSS_CS_CONFIG_NODE_ID:
		if (code == LSS_EC_NODE_ID_RANGE)
			return "node-ID out of range";
		break;
	case LSS_CS_CONFIG_BIT_TIMING:
		if (code == LSS_EC_BIT_TIMING_UNSUPP)
			return "bit timing not supported";
		break;
	case LSS_CS_STORE:
		if (code == LSS_EC_STORE_UNSUPP)
			return "store configuration not supported";
		if (code == LSS_EC_STORE_ACCESS)
			return "storage media access error";
		break;
	default:
		break;
	}
	return "reserved error code";
}

uint16_t lss_bit_rate_kbit(uint8_t index)
{
	/* CiA 305 table 0; index 5 is reserved (it was 100 kbit/s once). */
	static const uint16_t kbit[] = { 1000, 800, 500, 250, 125, 0, 50, 20, 10 };

	return index < sizeof(kbit) / sizeof(kbit[0]) ? kbit[index] : 0;
}
