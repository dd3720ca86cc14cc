"""`orbitrig dashboard`: the operator's live view of a rig in the browser.

The web server (server.py) opens one MQTT connection per signed-in person
(session.py), as that broker user: the broker authenticates and its ACL
decides who may command. The page (static/) draws status, progress, drives,
sensors, the averaged revolution and orbit, results and the manual setting
the run waits for, from the rig service's topics (docs/protocols/mqtt.md).
For a shift (docs/dashboard.md): trends (trend.py), latched alarms and their
acknowledgement (alarms.py) and the choice among the rigs of the broker (rigs.py).
"""
