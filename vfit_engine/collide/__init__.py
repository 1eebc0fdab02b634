"""collide"""
