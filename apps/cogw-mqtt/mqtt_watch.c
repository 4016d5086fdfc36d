/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_watch.c - process values (mqtt_watch.h): refused
 * while the daemon's mailbox has no device-object watch.
 */
#include "apps/cogw-mqtt/mqtt_watch.h"

#include <stdio.h>

int mqtt_watch_request(bridge *b, const mqtt_request *r, char *err, size_t errlen)
{
	(void)b;
	snprintf(err, errlen,
		 "%s: the daemon's mailbox has no watch of device objects yet; read the "
		 "object with sdo_read (docs/mqtt.md \"Process values\")",
		 mqtt_op_to_string(r->op));
	return -1;
}
