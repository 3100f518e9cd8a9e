"""The rosbridge v2 server: the hub of one process and its connections, the consumer, the
relay between processes, service and action calls, the teleop gate, the fleet feed, the
server's own services (rosapi, cloud), parameters, the listings and the transport.
"""
