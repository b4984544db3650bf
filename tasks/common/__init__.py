"""Pieces shared by the G1 tasks: the table, postures, action terms, generic observation and reward terms."""
