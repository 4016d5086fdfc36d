/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_api_events.c - libcogw, event subscriptions; the transport remembers
 * them per line and subscribes again after a re-registration.
 * Each call is one request and its answer through client_call()
 * (mailbox/client_internal.h).
 */
#include "mailbox/client_internal.h"

#include <string.h>

int cogw_subscribe(cogw *h, unsigned line, uint32_t classes, const mbx_raw_filter *filters,
		   size_t n_filters, unsigned timeout_ms)
{
	mbx_subscribe_req r = { .classes = classes };
	mbx_subscribe_resp s;

	if (n_filters > MBX_RAW_FILTERS_MAX || (n_filters && !filters))
		return COGW_E_INVAL;
	r.n_filters = (uint8_t)n_filters;
	if (n_filters)
		memcpy(r.filters, filters, n_filters * sizeof *filters);
	int rc = client_call(h, line, MBX_CMD_SUBSCRIBE, &r, sizeof r, NULL, 0, &s, sizeof s, NULL,
			     NULL, timeout_ms);

	if (rc == 0) /* remembered for a re-registration */
		rc = client_subscribed(h, line, classes, r.n_filters, r.filters);
	return rc;
}

int cogw_unsubscribe(cogw *h, unsigned line, uint32_t classes, unsigned timeout_ms)
{
	mbx_unsubscribe_req r = { .classes = classes };
	mbx_subscribe_resp s;

	int rc = client_call(h, line, MBX_CMD_UNSUBSCRIBE, &r, sizeof r, NULL, 0, &s, sizeof s,
			     NULL, NULL, timeout_ms);

	if (rc == 0)
		client_unsubscribed(h, line, classes);
	return rc;
}
