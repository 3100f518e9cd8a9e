"""Recording every robot's topics into MCAP files, and reading them back.

``recorder`` taps every topic of the bus (``hub.tap``, the one way) and writes off the
relay loop; ``files`` holds the MCAP files; ``plans`` reads what each building records and
keeps; ``export`` streams any time range as one MCAP file or ROS 1 bag.
"""
