"""rover_cli"""
