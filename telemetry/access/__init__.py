"""Who may do what on a connection or a stream: the rules of who may use which names
(``rules``, plain Python), the decisions taken with the database (``decisions``: who is
connecting and what each name's owner allows), access changes announced after commit
(``revocation``) and what they do to open connections and streams (``review``).
"""
