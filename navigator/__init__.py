"""navigator"""
