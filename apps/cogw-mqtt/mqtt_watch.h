/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_watch.h - process values: the one place where the
 * bridge meets the daemon's typed watch of device objects (docs/mqtt.md
 * "Process values"). A watch names net, node, index, sub, a type and a
 * minimum interval; its values are published on
 *   <prefix>/<gateway>/net/<net>/node/<node>/value/<index>/<sub>
 * at most once per interval (the newest value wins), so that a 1 kHz PDO
 * does not flood the broker.
 *
 * The daemon this bridge is built against has no watch command in its
 * mailbox protocol yet: mqtt_watch_request() refuses watch_add and
 * watch_remove with a reason that says so, and nothing is published as a
 * value. When the mailbox gains the watch (commands and a value event),
 * this module is what changes: the request starts the watch through
 * libcogw and the value events are throttled here per watch.
 */
#ifndef COGW_MQTT_WATCH_H
#define COGW_MQTT_WATCH_H

#include <stddef.h>

#include "apps/cogw-mqtt/bridge.h"

/* watch_add / watch_remove: 0 when done, else -1 with the reason. */
int mqtt_watch_request(bridge *b, const mqtt_request *r, char *err, size_t errlen);

#endif /* COGW_MQTT_WATCH_H */
