"""Reinforcement-learning agents trained on the vcnc-gym environments."""
