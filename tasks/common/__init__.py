"""Pieces shared by the G1 table-top tasks: the table, robot postures and generic observation terms."""
