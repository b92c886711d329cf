"""The robot's joint-state stream: ``wire`` (HRS1 frames, decoder; pure) and ``link`` (the TCP
client, polled, reconnecting)."""
