"""The rig service under MQTT control: the topic contract and the service that runs one run at a time."""
