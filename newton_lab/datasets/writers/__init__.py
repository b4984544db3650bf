"""Background writers of ``collect``: one design, a writer process (``process``, run by ``process_main``) that takes
whole column blocks (``columns``) through shared memory, with a writer thread (``background_thread``) where a process
cannot start; ``child_process`` starts children, ``interrupts`` turns Ctrl-C into an end that keeps what is
written."""
