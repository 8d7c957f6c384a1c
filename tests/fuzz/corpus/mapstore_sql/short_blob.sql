UPDATE entries SET what_mu=x'00000000' WHERE id=1;
