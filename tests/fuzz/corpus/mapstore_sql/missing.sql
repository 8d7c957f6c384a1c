DELETE FROM meta WHERE key='layout_dim'; UPDATE entries SET x=NULL WHERE id=2;
