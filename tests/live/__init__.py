"""Live views: the feeds (an MCAP file being written, a Foxglove WebSocket server), the LiveView, the live command."""
